#!/usr/bin/env python3
"""Tabulate the summary.json of one or more grainwave runs.

    postprocess/summaries.py out/*/summary.json [--metrics L1_rho,wall_s] [--csv table.csv]

Prints one row per run: scene, ranks, steps, wall time, and the chosen metrics (all metrics when
none are named). The run-time-vs-error harness reads the same files.
"""
import argparse
import csv
import json
import sys


def load(paths):
    rows = []
    for path in paths:
        with open(path) as f:
            s = json.load(f)
        row = {"run": path, "scene": s.get("scene"), "ranks": s.get("ranks"),
               "steps": s.get("steps"), "t_final": s.get("t_final"), "wall_s": s.get("wall_s"),
               "status": s.get("status")}
        row.update(s.get("metrics", {}))
        rows.append(row)
    return rows


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("summaries", nargs="+", help="summary.json files")
    parser.add_argument("--metrics", default="", help="comma-separated metric names")
    parser.add_argument("--csv", help="also write the table as CSV")
    args = parser.parse_args(argv)
    rows = load(args.summaries)
    fixed = ["scene", "ranks", "steps", "t_final", "wall_s", "status"]
    metrics = [m for m in args.metrics.split(",") if m] or sorted(
        {k for r in rows for k in r} - set(fixed) - {"run"})
    columns = fixed + metrics
    print(" | ".join(columns))
    for r in rows:
        print(" | ".join("" if r.get(c) is None else (f"{r[c]:.6g}" if isinstance(r[c], float)
                                                        else str(r[c])) for c in columns))
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["run"] + columns, extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main(sys.argv[1:])
