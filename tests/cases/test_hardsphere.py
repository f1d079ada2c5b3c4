"""Hard-sphere cases (particles/hardsphere/): conservation (002 App. A), Enskog collision rate,
Haff's law, bouncing under gravity, replicated MPI runs, restart, failure and the App. A plot."""
import csv
import glob
import os
import subprocess
import sys

import h5py
import numpy as np

from gwtest import SOURCE, case, expect, grainwave, main, scratch, summary


def run_case(name, *overrides, ranks=None, out=None):
    out = out or scratch(name)
    grainwave("run", case(f"{name}.toml"), "--out", out, *overrides, ranks=ranks, check=0)
    return out, summary(out)


def appendix_a_conservation():
    out, s = run_case("hs_appendix_a")
    m = s["metrics"]
    expect(s["counts"]["collisions"] >= 30, f"many collisions in 10 s ({s['counts']['collisions']})")
    expect(abs(m["energy_rel_drift"]) <= 1e-12, f"kinetic energy constant: drift {m['energy_rel_drift']:.2e}")
    expect(m["momentum_abs_drift"] <= 1e-12, f"linear momentum constant: drift {m['momentum_abs_drift']:.2e}")
    expect(m["max_overlap_over_radius"] <= 1e-10, f"no overlap: {m['max_overlap_over_radius']:.2e}")
    rows = list(csv.DictReader(open(os.path.join(out, "totals.csv"))))
    scale = max(abs(float(r[k])) for r in rows for k in ("Lx", "Ly", "Lz"))
    checked = with_collisions = 0
    worst = 0.0
    for a, b in zip(rows, rows[1:]):
        if b["crossings"] != a["crossings"] or int(b["boundary_collisions"]) > 0:
            continue  # L about the origin jumps when a position wraps (002 Fig. A.3)
        checked += 1
        with_collisions += int(b["collisions"]) > 0
        worst = max(worst, max(abs(float(b[k]) - float(a[k])) for k in ("Lx", "Ly", "Lz")))
    expect(with_collisions >= 20, f"{with_collisions} steps with collisions and no crossing")
    expect(worst <= 1e-12 * scale, f"angular momentum constant between crossings: worst change "
           f"{worst:.2e} of |L| {scale:.3g} over {checked} steps")
    proc = subprocess.run([sys.executable, os.path.join(SOURCE, "postprocess",
                                                        "plot_hard_sphere_totals.py"), out,
                           "--t-max", "2"], capture_output=True, text=True)
    expect(proc.returncode == 0 and os.path.getsize(os.path.join(out, "totals.png")) > 10000,
           f"Figs A.1-A.3 plotted to totals.png {proc.stderr}")


def gas_collision_rate_enskog():
    out, s = run_case("hs_gas")
    m = s["metrics"]
    dev = m["collision_frequency"] / m["collision_frequency_enskog"] - 1
    expect(abs(m["packing_fraction"] - 0.2618) < 1e-4, f"packing fraction {m['packing_fraction']:.4f}")
    expect(abs(dev) <= 0.02, f"collision frequency {m['collision_frequency']:.4f} vs Enskog "
           f"{m['collision_frequency_enskog']:.4f}: {100 * dev:+.2f}%")
    expect(abs(m["energy_rel_drift"]) <= 1e-12, f"elastic gas keeps its energy ({m['energy_rel_drift']:.1e})")
    expect(m["max_overlap_over_radius"] <= 1e-10, "no overlap")
    print(f"collisions_per_s {m['collisions_per_s']:.3g} (run throughput, event-driven)")


def cooling_haff():
    out, s = run_case("hs_cooling")
    m = s["metrics"]
    expect(m["temperature_final_over_initial"] < 0.35,
           f"the gas cooled to {m['temperature_final_over_initial']:.3f} of its temperature")
    expect(m["haff_max_rel_dev"] <= 0.05, f"temperature follows Haff's law within "
           f"{100 * m['haff_max_rel_dev']:.2f}% (t0 = {m['haff_t0']:.3g})")
    expect(m["max_overlap_over_radius"] <= 1e-10, "no overlap")


def bounce_under_gravity():
    out, s = run_case("hs_bounce")
    expect(s["counts"]["wall_hits"] > 40 and s["counts"]["collisions"] > 0,
           f"balls hit the floor and each other ({s['counts']})")
    expect(s["metrics"]["max_overlap_over_radius"] <= 1e-10, "no overlap")
    last = sorted(glob.glob(os.path.join(out, "output_*.h5")))[-1]
    with h5py.File(last, "r") as f:
        z, r = np.array(f["particles/position"])[:, 2], np.array(f["particles/radius"])
    expect(np.all(z - r >= -1e-10) and np.all(z + r <= 12 + 1e-10), "every ball stays between the walls")


def modes_and_ranks_agree():
    # Replicated colliders: 1 and 2 ranks give identical files; retrospective and event-driven
    # agree on a short elastic run (before chaos amplifies round-off differences).
    short = ["--set", "run.t_end=0.5", "--set", "particles.count=200", "--set",
             "particles.placement=random", "--set", "run.dt=0.05"]
    finals = {}
    for label, extra, ranks in [("event_1", [], None), ("event_2", [], 2),
                                ("retro_1", ["--set", "particles.collisions=retrospective"], None)]:
        out, s = run_case("hs_gas", *short, *extra, ranks=ranks, out=scratch("agree_" + label))
        with h5py.File(sorted(glob.glob(os.path.join(out, "output_*.h5")))[-1], "r") as f:
            finals[label] = (s, np.array(f["particles/position"]), np.array(f["particles/velocity"]))
    (s1, x1, v1), (s2, x2, v2), (s3, x3, v3) = finals["event_1"], finals["event_2"], finals["retro_1"]
    expect(np.array_equal(x1, x2) and np.array_equal(v1, v2) and s1["counts"] == s2["counts"],
           "event-driven run identical on 1 and 2 ranks")
    expect(s1["counts"]["collisions"] == s3["counts"]["collisions"],
           f"same collision count in both modes ({s1['counts']['collisions']})")
    expect(np.max(np.abs(x1 - x3)) < 1e-8 and np.max(np.abs(v1 - v3)) < 1e-8,
           f"same final state in both modes (max diff {max(np.max(np.abs(x1 - x3)), np.max(np.abs(v1 - v3))):.1e})")


def restart_bitwise():
    settings = ["--set", "run.t_end=2.0", "--set", "output.checkpoint_every_steps=7"]
    ref, _ = run_case("hs_gas", *settings, out=scratch("hs_restart_ref"))
    killed = scratch("hs_restart_killed")
    proc = grainwave("run", case("hs_gas.toml"), *settings, "--set", "debug.kill_at_step=12",
                     "--out", killed)
    expect(proc.returncode in (-9, 137), "killed at step 12")
    grainwave("run", case("hs_gas.toml"), *settings, "--restart", killed, check=0)
    # A run ended at t = 1.3 (its end-of-run checkpoint is off the periodic ones, at step 13)
    # and taken on to t = 2: its events go on from the checkpoint's schedule, not predicted
    # afresh, so it ends where the uninterrupted run does.
    extended = scratch("hs_restart_extended")
    grainwave("run", case("hs_gas.toml"), *settings, "--set", "run.t_end=1.3", "--out", extended)
    grainwave("run", case("hs_gas.toml"), *settings, "--restart", extended, check=0)
    for label, out in (("killed at step 12", killed), ("extended from t = 1.3", extended)):
        a, b = summary(ref), summary(out)
        expect(a["counts"] == b["counts"], f"{label}: same counts after restart ({b['counts']})")
        with h5py.File(sorted(glob.glob(os.path.join(ref, "output_*.h5")))[-1]) as f, \
             h5py.File(sorted(glob.glob(os.path.join(out, "output_*.h5")))[-1]) as g:
            for k in ("position", "velocity", "angular_velocity"):
                expect(np.array_equal(f["particles"][k], g["particles"][k]),
                       f"{label}: {k} bitwise equal after restart")


def overlap_is_a_failure():
    # Placing spheres on top of each other is caught before anything runs.
    out = scratch("hs_overlap")
    proc = grainwave("check", case("hs_appendix_a.toml"), "--set", "particles.placement=cubic",
                     "--set", "particles.radius=1.2")
    expect(proc.returncode == 2 and "particles.radius" in proc.stderr,
           f"overlapping lattice rejected: {proc.stderr.strip()}")
    del out


main({f.__name__: f for f in [appendix_a_conservation, gas_collision_rate_enskog, cooling_haff,
                               bounce_under_gravity, modes_and_ranks_agree, restart_bitwise,
                               overlap_is_a_failure]})
