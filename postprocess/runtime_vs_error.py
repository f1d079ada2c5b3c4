#!/usr/bin/env python3
"""Log-log plot of wall time against L1 density error from bench/runtime_vs_error.py's table:
one panel per case, uniform grids and adaptive grids (labelled by eps) as two lines.

usage: postprocess/runtime_vs_error.py OUT_FOLDER   (reads runtime_vs_error.csv, writes .png)
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    folder = sys.argv[1]
    with open(os.path.join(folder, "runtime_vs_error.csv")) as f:
        rows = list(csv.DictReader(f))
    cases = sorted({r["case"] for r in rows})
    fig, axes = plt.subplots(1, len(cases), figsize=(5 * len(cases), 4), squeeze=False)
    for ax, name in zip(axes[0], cases):
        for kind, marker in (("uniform", "o-"), ("adaptive", "s--")):
            sel = [r for r in rows if r["case"] == name and r["grid"].startswith(kind)]
            err = [float(r["L1_rho"]) for r in sel]
            wall = [float(r["wall_s"]) for r in sel]
            ax.loglog(err, wall, marker, label=kind)
            for r, e, w in zip(sel, err, wall):
                ax.annotate(r["eps"] or r["grid"].split()[-1], (e, w), fontsize=7)
        ax.set_xlabel("L1 density error")
        ax.set_ylabel("wall time [s]")
        ax.set_title(name)
        ax.legend()
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    path = os.path.join(folder, "runtime_vs_error.png")
    fig.savefig(path, dpi=120)
    print(path)


if __name__ == "__main__":
    main()
