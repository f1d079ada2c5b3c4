#!/usr/bin/env python3
"""Plot a hard-sphere run's totals like 002 Figs A.1-A.3.

    postprocess/plot_hard_sphere_totals.py OUTPUT_FOLDER [--out totals.png]

Reads OUTPUT_FOLDER/totals.csv (per-step kinetic energy K, linear momentum P, angular momentum L
about the origin, collision and periodic-crossing counts) and, if present, collisions.csv (the
time of every collision). Draws K, P and L against time with solid vertical lines at collisions
and dashed lines at steps in which a particle crossed a periodic boundary (L jumps there).
"""
import argparse
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_csv(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]} if rows else {}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder")
    parser.add_argument("--out", help="PNG file (default FOLDER/totals.png)")
    parser.add_argument("--t-max", type=float, help="plot only t <= T_MAX (002 shows 2 of 10 s)")
    args = parser.parse_args()
    totals = read_csv(os.path.join(args.folder, "totals.csv"))
    t = totals["t"]
    keep = [i for i, x in enumerate(t) if args.t_max is None or x <= args.t_max]
    t = [t[i] for i in keep]
    collisions_path = os.path.join(args.folder, "collisions.csv")
    collision_times = []
    if os.path.exists(collisions_path):
        collision_times = [x for x in read_csv(collisions_path).get("t", [])
                           if args.t_max is None or x <= args.t_max]
    crossing_steps = [totals["t"][i] for i in keep[1:]
                      if totals["crossings"][i] > totals["crossings"][i - 1]]

    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    panels = [("K", ["kinetic_energy"], "kinetic energy $K$"),
              ("P", ["px", "py", "pz"], "linear momentum $P$"),
              ("L", ["Lx", "Ly", "Lz"], "angular momentum $L$ (origin)")]
    for ax, (_, keys, label) in zip(axes, panels):
        for k in keys:
            ax.plot(t, [totals[k][i] for i in keep], label=k)
        for c in collision_times:
            ax.axvline(c, color="k", lw=0.4, alpha=0.5)
        if keys[0] == "Lx":
            for c in crossing_steps:
                ax.axvline(c, color="k", lw=0.4, ls="--", alpha=0.5)
        ax.set_ylabel(label)
        if len(keys) > 1:
            ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time $t$")
    fig.suptitle("hard-sphere totals: solid lines collisions, dashed periodic crossings")
    fig.tight_layout()
    out = args.out or os.path.join(args.folder, "totals.png")
    fig.savefig(out, dpi=120)
    print(out)


if __name__ == "__main__":
    main()
