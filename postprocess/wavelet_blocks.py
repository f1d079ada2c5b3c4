#!/usr/bin/env python3
"""Plot a 2D adaptive-grid output: the field u on every block with the block outlines coloured
by level (and a level histogram), from the HDF5 written by a [wavelet] scene.

    python3 postprocess/wavelet_blocks.py out/wavelet_disc_2d/output_000005.h5 [-o blocks.png]

Block geometry comes from the output's XDMF sidecar (origin and spacing of each patch), so the
script needs only h5py, numpy, matplotlib and the standard library.
"""
import argparse
import os
import re
import xml.etree.ElementTree as ET

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def block_geometry(sidecar):
    """(origin_xy, spacing_xy) per block, in block order, from the per-output XDMF sidecar."""
    geometry = {}
    for grid in ET.parse(sidecar).getroot().iter("Grid"):
        match = re.fullmatch(r"block_(\d+)", grid.get("Name", ""))
        if not match:
            continue
        items = grid.find("Geometry").findall("DataItem")
        origin = [float(v) for v in items[0].text.split()][::-1]  # XDMF lists z y x
        spacing = [float(v) for v in items[1].text.split()][::-1]
        geometry[int(match.group(1))] = (origin, spacing)
    return [geometry[k] for k in sorted(geometry)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", help="output_NNNNNN.h5 of a 2D [wavelet] run")
    parser.add_argument("-o", "--out", default=None, help="image file (default: next to the output)")
    args = parser.parse_args()

    sidecar = os.path.splitext(args.output)[0] + ".wavelet.xmf"
    with h5py.File(args.output, "r") as f:
        g = f["wavelet"]
        if int(g.attrs["dimension"]) != 2:
            raise SystemExit("this plot is for 2D outputs")
        u = np.array(g["u"])
        level = np.array(g["level"])[:, 0]
        time = float(f.attrs["time"])
    geometry = block_geometry(sidecar)
    bs = int(round(np.sqrt(u.shape[1])))
    levels = sorted(set(level.tolist()))
    colours = plt.cm.viridis(np.linspace(0, 1, max(len(levels), 2)))

    fig, (ax, hist) = plt.subplots(1, 2, figsize=(11, 5), gridspec_kw={"width_ratios": [3, 1]})
    for b, ((x0, y0), (dx, dy)) in enumerate(geometry):
        values = u[b].reshape(bs, bs)  # rows: y, columns: x
        extent = (x0 - dx / 2, x0 + (bs - 0.5) * dx, y0 - dy / 2, y0 + (bs - 0.5) * dy)
        ax.imshow(values, origin="lower", extent=extent, vmin=u.min(), vmax=u.max(), cmap="Greys")
        colour = colours[levels.index(level[b])]
        ax.add_patch(plt.Rectangle((x0, y0), bs * dx, bs * dy, fill=False, lw=0.6, ec=colour))
    ax.set_title(f"u and blocks at t = {time:.4g}")
    ax.set_aspect("equal")
    ax.autoscale()
    hist.bar([str(l) for l in levels], [int(np.sum(level == l)) for l in levels], color=colours[: len(levels)])
    hist.set_xlabel("level")
    hist.set_ylabel("blocks")
    out = args.out or os.path.splitext(args.output)[0] + "_blocks.png"
    fig.tight_layout()
    fig.savefig(out, dpi=150)
    print(out)


if __name__ == "__main__":
    main()
