#!/usr/bin/env python3
"""Profiles and contour maps of the DEM bin statistics, like 002 Figs 3.6 and 3.10-3.15.

Reads a curtain-state file (group /profiles) or a DEM output file (group /dem_statistics) and
writes FILE_profiles.png: contour maps of the solid volume fraction beta, <u> and <v>, and
beta(x), <v>(x) and v'(x) at several heights (rows of bins).

    python3 postprocess/plot_dem_profiles.py out/curtain_small/curtain_state.h5 [--rows 4]
"""
import argparse
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load(path):
    with h5py.File(path, "r") as f:
        g = f["profiles"] if "profiles" in f else f["dem_statistics"]
        data = {k: np.array(g[k]) for k in ("x", "y", "beta", "u_mean", "v_mean", "u_rms", "v_rms", "count")}
        data["samples"] = int(g.attrs["samples"])
    return data


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--rows", type=int, default=4, help="heights for the x profiles")
    parser.add_argument("--out", help="output PNG (default: beside the file)")
    args = parser.parse_args()
    d = load(args.file)
    x, y = d["x"] * 1e3, d["y"] * 1e3  # mm
    seen = d["count"] > 0
    fig, axes = plt.subplots(2, 3, figsize=(15, 9))
    maps = [("beta", r"$\beta$", "viridis"), ("u_mean", r"$\langle u\rangle$ [m/s]", "coolwarm"),
            ("v_mean", r"$\langle v\rangle$ [m/s]", "magma")]
    for ax, (key, label, cmap) in zip(axes[0], maps):
        values = np.where(seen, d[key], np.nan) if key != "beta" else d[key]
        mesh = ax.pcolormesh(x, y, values, shading="nearest", cmap=cmap)
        fig.colorbar(mesh, ax=ax, label=label)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
        ax.set_title(label)
    occupied = np.where(seen.any(axis=1))[0]
    rows = occupied[np.linspace(0, len(occupied) - 1, min(args.rows, len(occupied))).astype(int)] if len(occupied) else []
    for key, ax, label in (("beta", axes[1][0], r"$\beta$"), ("v_mean", axes[1][1], r"$\langle v\rangle$ [m/s]"),
                           ("v_rms", axes[1][2], r"$v'$ [m/s]")):
        for r in rows:
            values = np.where(seen[r], d[key][r], np.nan)
            ax.plot(x, values, "o-", ms=3, label=f"y = {y[r]:.2f} mm")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    fig.suptitle(f"{os.path.basename(args.file)}: {d['samples']} samples")
    fig.tight_layout()
    out = args.out or os.path.splitext(args.file)[0] + "_profiles.png"
    fig.savefig(out, dpi=90)
    print(out)


if __name__ == "__main__":
    main()
