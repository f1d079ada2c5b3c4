"""The same scene on 1 and 2 MPI ranks gives the same result."""
import glob
import os

import h5py
import numpy as np

from gwtest import case, expect, grainwave, main, scratch, summary


def demo_on_1_and_2_ranks():
    settings = ["--set", "run.t_end=0.5", "--set", "particles.count=300"]
    results = {}
    for ranks in (1, 2):
        out = scratch(f"mpi_{ranks}")
        grainwave("run", case("demo.toml"), *settings, "--out", out, ranks=ranks, check=0)
        s = summary(out)
        expect(s["ranks"] == ranks, f"summary.json records {ranks} rank(s)")
        last = sorted(glob.glob(os.path.join(out, "output_*.h5")))[-1]
        with h5py.File(last, "r") as f:
            results[ranks] = (s, {k: np.array(f["particles"][k]) for k in f["particles"]})
    (s1, a), (s2, b) = results[1], results[2]
    expect(s1["counts"] == s2["counts"], f"same counts {s1['counts']}")
    expect(s1["steps"] == s2["steps"], "same number of steps")
    for key in a:
        # Particles are independent in free flight and files are ordered by id: bitwise equal.
        expect(np.array_equal(a[key], b[key]), f"particles/{key} bitwise equal on 1 and 2 ranks")


main({"demo_on_1_and_2_ranks": demo_on_1_and_2_ranks})
