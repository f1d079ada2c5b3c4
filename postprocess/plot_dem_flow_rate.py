#!/usr/bin/env python3
"""Mass flow rate against fill height for a draining hopper, like 002 Fig. 3.4.

Reads flow.csv of one or more DEM runs (t, drained_mass, mass_above_plane, fill_top) and writes
flow_rate.png beside the first: the rate is the slope of the drained mass over a sliding window
(--window seconds), plotted against the fill top at the window's centre.

    python3 postprocess/plot_dem_flow_rate.py out/hopper_drain/flow.csv [more.csv ...] [--window 0.1]
"""
import argparse
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def rate_vs_height(path, window):
    with open(path) as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    t = np.array([r["t"] for r in rows])
    drained = np.array([r["drained_mass"] for r in rows])
    top = np.array([r["fill_top"] for r in rows])
    started = np.argmax(drained > 0) if np.any(drained > 0) else len(t)
    heights, rates = [], []
    for i in range(started, len(t)):
        j = np.searchsorted(t, t[i] + window)
        if j >= len(t):
            break
        rates.append((drained[j] - drained[i]) / (t[j] - t[i]))
        heights.append(top[(i + j) // 2])
    return np.array(heights), np.array(rates)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--window", type=float, default=0.1, help="slope window [s]")
    parser.add_argument("--out", help="output PNG (default: flow_rate.png beside the first file)")
    args = parser.parse_args()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for path in args.files:
        h, r = rate_vs_height(path, args.window)
        ax.plot(h * 1e3, r, "o-", ms=3, label=os.path.basename(os.path.dirname(os.path.abspath(path))))
    ax.set_xlabel("fill top H [mm]")
    ax.set_ylabel(r"mass flow rate $\dot m$ [kg/s (per m in 2D)]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.files[0])), "flow_rate.png")
    fig.savefig(out, dpi=100)
    print(out)


if __name__ == "__main__":
    main()
