"""Soft-sphere DEM cases (particles/dem/, DemSystem): single collisions against 002 Eqs 3.10 and
3.17, energy drift of elastic collisions, a settled bed's packing fraction, hopper drain, the
particle curtain, replicated MPI runs and bitwise restart with contact history."""
import csv
import glob
import os
import subprocess
import sys

import h5py
import numpy as np

from gwtest import SOURCE, case, expect, grainwave, main, scratch, summary

WALL = ['dem.collision_partner="wall"', 'dem.boundary_x=["wall", "wall"]']


def run_case(name, *overrides, ranks=None, out=None, tag=""):
    out = out or scratch(name + tag)
    args = []
    for o in overrides:
        args += ["--set", o]
    grainwave("run", case(f"{name}.toml"), "--out", out, *args, ranks=ranks, check=0)
    return out, summary(out)


def check_collision(m, label):
    e, e_meas = m["restitution_target"], m["restitution_measured"]
    tau, tau_meas = m["contact_duration_theory"], m["contact_duration"]
    expect(abs(e_meas / e - 1) <= 0.005, f"{label}: restitution {e_meas:.6f} vs e = {e} "
           f"({100 * (e_meas / e - 1):+.3f} %, limit 0.5 %)")
    expect(abs(tau_meas / tau - 1) <= 0.01, f"{label}: contact duration {tau_meas:.6e} s vs Eq. 3.17 "
           f"{tau:.6e} s ({100 * (tau_meas / tau - 1):+.3f} %, limit 1 %)")


def collision_restitution_linear():
    """Linear spring-dashpot, N = 50, velocity Verlet: pair at e = 0.5, 0.9, 0.97 and wall."""
    for e in (0.5, 0.9, 0.97):
        _, s = run_case("dem_collision", f"dem.restitution={e}", tag=f"_{e}")
        check_collision(s["metrics"], f"pair e = {e}")
    for e in (0.5, 0.9):
        _, s = run_case("dem_collision", f"dem.restitution={e}", *WALL, tag=f"_wall_{e}")
        check_collision(s["metrics"], f"wall e = {e}")


def collision_energy_drift():
    """e = 1, mu = 0, N = 50: relative energy change over >= 1000 collisions below 1e-4."""
    _, s = run_case("dem_collision", "dem.restitution=1.0", "run.t_end=0.143")
    n, drift = s["counts"]["collisions"], s["metrics"]["energy_rel_drift"]
    expect(n >= 1000, f"{n} collisions")
    expect(abs(drift) < 1e-4, f"energy drift {drift:.2e} over {n} elastic collisions (limit 1e-4)")


def collision_laws_on_1_and_2_ranks():
    """Each law pairing (the kernels' golden cases) through the scene, serially and on 2 ranks:
    the replicated DEM gives identical numbers; linear-law results match Eqs 3.10/3.17."""
    variants = {
        "linear_verlet": ["dem.restitution=0.9"],
        "linear_rk2": ["dem.restitution=0.9", 'dem.integrator="runge_kutta2"'],
        "linear_wall_rk2": ["dem.restitution=0.5", 'dem.integrator="runge_kutta2"', *WALL],
        "hertz": ['dem.normal_law="hertz"', "dem.restitution=0.8"],
        "coulomb_spring": ['dem.tangential_law="coulomb_spring"', "dem.friction=0.3"],
        "mindlin": ['dem.tangential_law="mindlin"', "dem.friction=0.3"],
    }
    for name, overrides in variants.items():
        _, one = run_case("dem_collision", *overrides, tag=f"_{name}_1")
        _, two = run_case("dem_collision", *overrides, ranks=2, tag=f"_{name}_2")
        for key in ("restitution_measured", "contact_duration", "kinetic_energy"):
            expect(one["metrics"][key] == two["metrics"][key],
                   f"{name}: {key} identical on 1 and 2 ranks ({one['metrics'][key]:.12g})")
        if "hertz" not in name:
            check_collision(one["metrics"], name)
        else:  # Hertz: e by construction; the duration at the reference speed (= impact speed)
            m = one["metrics"]
            expect(abs(m["restitution_measured"] / m["restitution_target"] - 1) <= 0.005,
                   f"hertz: restitution {m['restitution_measured']:.5f} vs {m['restitution_target']}")
            expect(abs(m["contact_duration"] / m["contact_duration_theory"] - 1) <= 0.01,
                   f"hertz: duration {m['contact_duration']:.4e} vs {m['contact_duration_theory']:.4e}")


def settled_bed_packing():
    out, s = run_case("dem_settle")
    m = s["metrics"]
    expect("gate_opened_at" in m, f"the bed came to rest (rms speed < 5 mm/s) at t = {m.get('gate_opened_at')}")
    phi = m["packing_fraction"]
    expect(0.58 <= phi <= 0.64, f"packing fraction {phi:.4f} between random loose and close packing")
    print(f"particle_steps_per_s {m['particle_steps_per_s']:.3g}, bytes_per_particle {m['bytes_per_particle']:.0f}")


def restart_bitwise_with_history():
    """A run stopped half way and restarted from its checkpoint (contact history, integrator
    forces) ends bit for bit where the uninterrupted run ends."""
    common = ["run.t_end=0.05", 'dem.tangential_law="coulomb_spring"', "output.interval=0.0"]
    full, _ = run_case("dem_settle", *common, tag="_full")
    part = scratch("dem_settle_part")
    grainwave("run", case("dem_settle.toml"), "--out", part, *sum([["--set", o] for o in common], []),
              "--set", "run.max_steps=2000", check=0)
    grainwave("run", case("dem_settle.toml"), "--out", part, "--restart", part,
              *sum([["--set", o] for o in common], []), check=0)
    last = lambda d: sorted(glob.glob(os.path.join(d, "output_*.h5")))[-1]
    with h5py.File(last(full)) as a, h5py.File(last(part)) as b:
        expect(a.attrs["time"] == b.attrs["time"], f"both end at t = {a.attrs['time']}")
        for key in ("position", "velocity", "angular_velocity"):
            same = np.array_equal(a["particles/" + key][()], b["particles/" + key][()])
            expect(same, f"{key} identical after the restart")


def hopper_drain_flow_rate():
    """002 Fig. 3.4, measured as 002 §3.3 does: one fill drains without recycling, so the fill
    height H falls steadily, and the mass flow rate is taken in 0.1 s windows against H. Above a
    critical height the rate is independent of H; below it the rate falls."""
    out, s = run_case("hopper_drain", "dem.count=1200", "run.t_end=2.2", "dem.flow_end=0.0",
                      "output.interval=0.0", tag="_full")
    expect(s["counts"]["particles_removed"] == 1200, f"the hopper drained ({s['counts']['particles_removed']} of 1200)")
    with open(os.path.join(out, "flow.csv")) as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    t = np.array([r["t"] for r in rows])
    drained = np.array([r["drained_mass"] for r in rows])
    top = np.array([r["fill_top"] for r in rows])
    above = np.array([r["mass_above_plane"] for r in rows])
    opened = s["metrics"]["gate_opened_at"]
    windows = []  # (mean fill top, rate); the first 0.1 s after the gate opened is start-up
    for a in np.arange(opened + 0.1, t[-1] - 0.1, 0.1):
        sel = (t >= a) & (t <= a + 0.1)
        if sel.sum() < 2 or above[sel][0] == 0:  # empty above the plane: drained
            break
        windows.append((top[sel].mean(), (drained[sel][-1] - drained[sel][0]) / (t[sel][-1] - t[sel][0])))
    h = np.array([w[0] for w in windows])
    rate = np.array([w[1] for w in windows])
    print("fill top [mm], rate [kg/s/m]:", [(round(1e3 * a), round(b, 2)) for a, b in windows])
    # Plateau: fill tops above 80 mm (about 27 D, 4.4 slit widths above the slit).
    plateau = rate[h >= 0.08]
    expect(len(plateau) >= 6, f"{len(plateau)} windows above the critical height")
    upper, lower = plateau[: len(plateau) // 2], plateau[len(plateau) // 2:]
    sigma = plateau.std(ddof=1)
    difference = upper.mean() - lower.mean()
    sigma_difference = sigma * np.sqrt(1 / len(upper) + 1 / len(lower))
    # Independent of H: the upper and the lower half of the plateau agree within three standard
    # errors of the window-to-window scatter, and within 10 %.
    expect(abs(difference) <= 3 * sigma_difference and abs(difference) <= 0.1 * plateau.mean(),
           f"rate independent of H above 80 mm: {upper.mean():.2f} (upper half) vs {lower.mean():.2f} kg/s/m "
           f"(lower half), difference {difference:+.2f} against 3 sigma = {3 * sigma_difference:.2f} "
           f"({100 * difference / plateau.mean():+.1f} %)")
    low = rate[h < 0.035]
    expect(len(low) >= 1 and low.mean() < 0.8 * plateau.mean(),
           f"below the critical height the rate falls: {low.mean():.2f} kg/s/m below 35 mm vs "
           f"{plateau.mean():.2f} on the plateau")
    proc = subprocess.run([sys.executable, os.path.join(SOURCE, "postprocess", "plot_dem_flow_rate.py"),
                           os.path.join(out, "flow.csv"), "--window", "0.1"], capture_output=True, text=True)
    png = os.path.join(out, "flow_rate.png")
    expect(proc.returncode == 0 and os.path.getsize(png) > 10000, f"rate vs fill height plotted to {png} {proc.stderr}")


def by_id(f, key):
    """A dataset of an output file's particles in id order (ranks write their own rows)."""
    order = np.argsort(f["particles/id"][()].ravel())
    return f["particles/" + key][()][order]


def hopper_drain_on_2_ranks():
    """The hopper cut into two slabs (x < 0 and x > 0, each rank owning one half of the funnel):
    the same mass flow rate as on one rank. The trajectories are bitwise the serial ones, so the
    rate agrees to the round-off of adding the two ranks' drained masses."""
    _, one = run_case("hopper_drain", "dem.count=300", tag="_r1")
    out, two = run_case("hopper_drain", "dem.count=300", ranks=2, tag="_r2")
    expect(two["counts"].get("ranks_in_slabs") == 2, "the run was cut into 2 slabs")
    a, b = one["metrics"]["mass_flow_rate"], two["metrics"]["mass_flow_rate"]
    expect(abs(a - b) <= 1e-12 * abs(a), f"mass flow rate {a:.12g} (1 rank) and {b:.12g} (2 ranks)")
    expect(one["counts"]["particles_removed"] == two["counts"]["particles_removed"],
           f"{two['counts']['particles_removed']} disks drained on both")
    with open(os.path.join(out, "log.txt")) as f:
        expect("2 slabs along x" in f.read(), "the log reports the decomposition")


def curtain_small_state():
    """The scaled curtain writes curtain_state.h5: beta just below the slit in 0.45-0.64, the
    curtain accelerates downwards and its width changes; info describes it; profiles plotted."""
    out, s = run_case("curtain_small")
    m = s["metrics"]
    beta = m["beta_below_slit"]
    expect(0.45 <= beta <= 0.64, f"beta below the slit {beta:.3f} over {m['statistics_samples']:.0f} samples")
    path = os.path.join(out, "curtain_state.h5")
    with h5py.File(path) as f:
        expect(f.attrs["grainwave_kind"] in (b"curtain_state", "curtain_state"), "a curtain-state file")
        x, v = f["particles/position"][()], f["particles/velocity"][()]
        for key in ("angular_velocity", "radius"):
            expect(f["particles/" + key].shape[0] == x.shape[0], f"{key} for every particle")
        expect(f["profiles/beta"].shape == (len(f["profiles/y"]), len(f["profiles/x"])), "beta profile on the bins")
        scene = bytes(np.array(f["scene_text"]).astype(np.uint8)).decode()
    expect("[dem_curtain]" in scene, "the scene that produced it is stored")
    expect(len(x) > 500 and np.all(x[:, 1] < 0), f"{len(x)} particles, all below the slit")
    # Bands 1 mm high from the slit down to the front: mean fall speed and width (std of x).
    bands = [(y0, (x[:, 1] >= y0) & (x[:, 1] < y0 + 1e-3)) for y0 in (-1e-3, -2e-3, -3e-3)]
    speed = [-v[m, 1].mean() for _, m in bands]
    width = [x[m, 0].std() for _, m in bands]
    print("bands (top mm, speed m/s, width mm):",
          [(round(y0 * 1e3), round(sp, 4), round(w * 1e3, 3)) for (y0, _), sp, w in zip(bands, speed, width)])
    expect(speed[2] > 1.1 * speed[0], f"gravity accelerates the curtain: {speed[0]:.3f} -> {speed[2]:.3f} m/s")
    change = width[1] / width[0] - 1
    expect(abs(change) > 0.02, f"the curtain {'narrows' if change < 0 else 'spreads'} as it falls: "
           f"width {width[0] * 1e3:.3f} -> {width[1] * 1e3:.3f} mm ({100 * change:+.1f} %)")
    info = grainwave("info", path, check=0).stdout
    expect("curtain_state" in info and "/profiles/beta" in info, "grainwave info describes the file")
    proc = subprocess.run([sys.executable, os.path.join(SOURCE, "postprocess", "plot_dem_profiles.py"), path],
                          capture_output=True, text=True)
    png = os.path.join(out, "curtain_state_profiles.png")
    expect(proc.returncode == 0 and os.path.getsize(png) > 20000, f"profiles plotted to {png} {proc.stderr}")
    expect(os.path.getsize(os.path.join(out, "statistics.csv")) > 1000, "statistics.csv written")


def hopper_restart_bitwise():
    """Restart across the gate opening, with particles leaving through the open outlet and the
    flow rate being measured: the final state and the flow rate are bit for bit the same."""
    common = ["dem.count=300", "run.t_end=0.5", "output.interval=0.0"]
    args = sum([["--set", o] for o in common], [])
    full, s_full = run_case("hopper_drain", *common, tag="_restart_full")
    part = scratch("hopper_drain_restart_part")
    grainwave("run", case("hopper_drain.toml"), "--out", part, *args, "--set", "run.max_steps=19500", check=0)
    grainwave("run", case("hopper_drain.toml"), "--out", part, "--restart", part, *args, check=0)
    s_part = summary(part)
    with h5py.File(sorted(glob.glob(os.path.join(part, "checkpoint_*.h5")))[0]) as f:
        before = f["system/dem/id"].shape[0]
    expect(before < 300, f"disks had left before the stop ({300 - before})")
    expect(s_full["metrics"]["gate_opened_at"] < 19500 * s_full["metrics"]["time_step"],
           "the gate opened before the stop")
    expect(s_full["counts"]["particles_removed"] > 0, f"{s_full['counts']['particles_removed']} disks drained")
    for key in ("mass_flow_rate", "gate_opened_at", "kinetic_energy"):
        expect(s_full["metrics"][key] == s_part["metrics"][key], f"{key} identical after the restart "
               f"({s_full['metrics'][key]:.12g})")
    last = lambda d: sorted(glob.glob(os.path.join(d, "output_*.h5")))[-1]
    with h5py.File(last(full)) as a, h5py.File(last(part)) as b:
        expect(np.array_equal(a["particles/position"][()], b["particles/position"][()]) and
               np.array_equal(a["particles/velocity"][()], b["particles/velocity"][()]),
               "positions and velocities identical after the restart")


def rough_hopper_walls():
    """hopper_drain with its funnel walls made rough (a row of fixed disks, 002 Fig. 3.3): the
    fixed disks never move, the fill still settles, the gate opens and the hopper drains."""
    with open(case("hopper_drain.toml")) as f:
        text = f.read()
    rough = text.replace("b = [-0.009, 0.0]\n", "b = [-0.009, 0.0]\nrough = true\n").replace(
        "b = [0.009, 0.0]\n", "b = [0.009, 0.0]\nrough = true\n")
    expect(rough.count("rough = true") == 2, "both funnel walls made rough")
    out = scratch("rough_hopper_walls")
    scene = os.path.join(out, "hopper_rough.toml")
    with open(scene, "w") as f:
        f.write(rough)
    grainwave("run", scene, "--out", out, "--set", "dem.count=300", "--set", "run.t_end=0.45", check=0)
    s = summary(out)
    expect(s["counts"]["fixed_particles"] > 20, f"{s['counts']['fixed_particles']} fixed wall disks")
    expect(s["metrics"]["mass_flow_rate"] > 0 and s["counts"]["particles_removed"] > 0,
           f"the hopper drains: {s['metrics']['mass_flow_rate']:.3f} kg/s/m, {s['counts']['particles_removed']} out")
    # On 2 ranks the cut at x = 0 runs through the slit: fixed wall disks are ghosts too.
    two = scratch("rough_hopper_walls_2")
    grainwave("run", scene, "--out", two, "--set", "dem.count=300", "--set", "run.t_end=0.45", ranks=2, check=0)
    files = sorted(glob.glob(os.path.join(out, "output_*.h5")))
    with h5py.File(files[-1]) as a, h5py.File(sorted(glob.glob(os.path.join(two, "output_*.h5")))[-1]) as b:
        same = all(np.array_equal(by_id(a, k), by_id(b, k)) for k in ("id", "flags", "position", "velocity"))
        expect(same, "in 2 slabs the state is bitwise that of 1 rank")
    with h5py.File(files[0]) as a, h5py.File(files[-1]) as b:
        fa, fb = a["particles/flags"][()] == 1, b["particles/flags"][()] == 1
        xa = a["particles/position"][()][fa]
        xb = b["particles/position"][()][fb]
        expect(np.array_equal(a["particles/id"][()][fa], b["particles/id"][()][fb]) and np.array_equal(xa, xb),
               "the rough-wall disks stay where they were placed")


def dense_bed_on_1_and_2_ranks():
    """A dense, frictional bed with tangential history, poured and settled, on 1 rank and cut
    into 2 and 3 slabs (domain decomposition, 002 §3.2.6): the contact forces are bitwise the
    serial ones, hence so are the states, while particles migrate with their contact history.
    Replicated runs on 2 ranks give the same. Then a checkpoint written by 2 ranks restarts on 2
    ranks bit for bit, and on 1 rank."""
    common = ["run.t_end=0.06", 'dem.tangential_law="coulomb_spring"', "output.interval=0.03"]
    one, s1 = run_case("dem_settle", *common, tag="_1rank")
    runs = {"2 slabs": run_case("dem_settle", *common, ranks=2, tag="_2ranks"),
            "3 slabs": run_case("dem_settle", *common, ranks=3, tag="_3ranks"),
            "2 ranks replicated": run_case("dem_settle", *common, 'dem.decomposition="replicated"',
                                           ranks=2, tag="_2replicated")}
    last = lambda d: sorted(glob.glob(os.path.join(d, "output_*.h5")))[-1]
    for label, (out, s) in runs.items():
        with h5py.File(last(one)) as a, h5py.File(last(out)) as b:
            for key in ("id", "position", "velocity", "angular_velocity"):
                expect(np.array_equal(by_id(a, key), by_id(b, key)), f"{label}: {key} identical to 1 rank")
        expect(s["counts"]["contacts"] == s1["counts"]["contacts"],
               f"{label}: {s['counts']['contacts']} contacts, as on 1 rank")
        e1, e2 = s1["metrics"]["kinetic_energy"], s["metrics"]["kinetic_energy"]
        expect(abs(e1 - e2) <= 1e-12 * e1, f"{label}: kinetic energy {e2:.15g} vs {e1:.15g}")
    with open(os.path.join(runs["2 slabs"][0], "log.txt")) as f:
        log = f.read()
    expect("2 slabs along x" in log and "migration" in log, "the log reports the slabs and the migration time")
    # Restart: stop the 2-slab run half way, continue on 2 ranks and on 1 rank.
    args = sum([["--set", o] for o in common], [])
    for ranks, tag in ((2, "2"), (1, "1")):
        part = scratch(f"dem_settle_restart_{tag}")
        grainwave("run", case("dem_settle.toml"), "--out", part, *args, "--set", "run.max_steps=2900",
                  ranks=2, check=0)
        grainwave("run", case("dem_settle.toml"), "--out", part, "--restart", part, *args,
                  ranks=ranks if ranks > 1 else None, check=0)
        with h5py.File(last(one)) as a, h5py.File(last(part)) as b:
            expect(a.attrs["time"] == b.attrs["time"], f"restart on {ranks}: ends at t = {b.attrs['time']}")
            same = all(np.array_equal(by_id(a, k), by_id(b, k)) for k in ("position", "velocity", "angular_velocity"))
            expect(same, f"written by 2 ranks, restarted on {ranks}: the state is bitwise that of the uninterrupted run")


def slabs_follow_a_settling_bed():
    """dem_settle cut along y (the direction it settles in) on 2 ranks: the fill collapses
    downwards, so cuts fixed at the start would leave the upper slab nearly empty; re-cut every
    500 steps by particle count, the two slabs stay balanced. Either way the state is bitwise
    that of 1 rank."""
    common = ["run.t_end=0.1", 'dem.decomposition_axis="y"', "output.interval=0.05"]
    one, _ = run_case("dem_settle", *common, tag="_y1")
    balanced, s = run_case("dem_settle", *common, "dem.rebalance_every=500", ranks=2, tag="_y2")
    fixed, f = run_case("dem_settle", *common, "dem.rebalance_every=0", ranks=2, tag="_y2fixed")
    ratio = s["counts"]["slab_particles_max"] / s["counts"]["slab_particles_min"]
    ratio_fixed = f["counts"]["slab_particles_max"] / f["counts"]["slab_particles_min"]
    expect(ratio <= 1.1, f"re-cut slabs hold {s['counts']['slab_particles_min']} and "
           f"{s['counts']['slab_particles_max']} particles (ratio {ratio:.3f})")
    expect(ratio_fixed > 1.2, f"without re-cuts the slabs would hold {f['counts']['slab_particles_min']} and "
           f"{f['counts']['slab_particles_max']} (ratio {ratio_fixed:.3f})")
    last = lambda d: sorted(glob.glob(os.path.join(d, "output_*.h5")))[-1]
    for label, out in (("re-cut", balanced), ("fixed", fixed)):
        with h5py.File(last(one)) as a, h5py.File(last(out)) as b:
            same = all(np.array_equal(by_id(a, k), by_id(b, k)) for k in ("id", "position", "velocity", "angular_velocity"))
            expect(same, f"{label} slabs along y: the state is bitwise that of 1 rank")


def neighbour_list_against_cell_search():
    """The Verlet list (dem.neighbour_skin, on by default) against the cell search at every
    step, on a pouring bed with tangential history: the same contacts, and the same states to
    round-off (only the order in which contact forces are added differs) while the list is
    rebuilt on a small fraction of the steps. A particle outrunning half the skin in one step
    stops the run with a message naming it."""
    common = ["run.t_end=0.02", 'dem.tangential_law="coulomb_spring"', "output.interval=0.01"]
    cells, s_cells = run_case("dem_settle", *common, "dem.neighbour_skin=0", tag="_cells")
    listed, s_list = run_case("dem_settle", *common, tag="_listed")
    last = lambda d: sorted(glob.glob(os.path.join(d, "output_*.h5")))[-1]
    with h5py.File(last(cells)) as a, h5py.File(last(listed)) as b:
        dx = np.abs(by_id(a, "position") - by_id(b, "position")).max()
        dv = np.abs(by_id(a, "velocity") - by_id(b, "velocity")).max()
        v = np.abs(by_id(a, "velocity")).max()
    expect(dx <= 1e-12 and dv <= 1e-9 * v, f"list vs cells: positions within {dx:.2g} m, velocities within {dv:.2g} m/s")
    expect(s_list["counts"]["contacts"] == s_cells["counts"]["contacts"],
           f"{s_list['counts']['contacts']} contacts with both")
    steps = 0.02 / s_list["metrics"]["time_step"]
    builds = s_list["counts"]["neighbour_list_builds"]
    expect(2 <= builds <= steps / 20, f"{builds} list builds in {steps:.0f} steps")
    with open(os.path.join(listed, "log.txt")) as f:
        expect("Verlet list (skin" in f.read(), "the log names the neighbour search")
    out = scratch("dem_settle_skin_too_small")
    proc = grainwave("run", case("dem_settle.toml"), "--out", out, "--set", "run.t_end=0.01",
                     "--set", "dem.neighbour_skin=1e-6")
    expect(proc.returncode == 3 and "raise dem.neighbour_skin" in proc.stderr and "particle id" in proc.stderr,
           f"a skin too thin for one step is a numerical failure (exit {proc.returncode}): "
           f"{proc.stderr.strip().splitlines()[-2:] if proc.stderr else ''}")


def read_statistics_csv(out):
    with open(os.path.join(out, "statistics.csv")) as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def channel_small_plug_flow():
    """Recycled channel flow (002 §3.3, smooth walls): no particle lost, a flat (plug) <v>
    profile as in 002 Fig. 3.6, a dense flow, and a mass flow rate through the plane that
    agrees with the binned statistics, rho beta <v> A."""
    # 100 Hz sampling instead of the 30 fps camera: the test runs only 0.25 s of flow.
    out, s = run_case("channel_small", "run.t_end=0.5", "dem_statistics.interval=0.01")
    m = s["metrics"]
    expect(s["counts"]["particles_removed"] == 0, "periodic recycling keeps every particle")
    rows = read_statistics_csv(out)
    v = np.array([r["v_mean"] for r in rows])
    beta = np.array([r["beta"] for r in rows])
    expect(np.all(v < 0), f"downward flow in every bin: <v> = {np.round(v, 4)} m/s")
    expect(v.max() / v.min() >= 0.8, f"plug flow: <v> across the channel within 20 % ({v.max() / v.min():.3f})")
    expect(0.5 <= m["beta_below_slit"] <= 0.66, f"dense flow in the channel: beta = {m['beta_below_slit']:.3f}")
    width, depth, rho = 0.03, 0.009, 2600.0
    from_bins = -rho * m["beta_below_slit"] * v.mean() * width * depth
    rate = m["mass_flow_rate"]
    # Mass conservation between two measurements of different kind; 10 % covers the sampling
    # noise of ~20 samples and the bin-edge error of centre counting.
    expect(abs(rate / from_bins - 1) <= 0.10, f"mass flow rate {rate:.4f} kg/s vs rho beta <v> A = "
           f"{from_bins:.4f} kg/s ({100 * (rate / from_bins - 1):+.1f} %)")


def channel_full():
    """Long validation run (label validate): the full-size channel of 002 §3.3."""
    out, s = run_case("channel")
    m = s["metrics"]
    rows = read_statistics_csv(out)
    v = np.array([r["v_mean"] for r in rows])
    expect(s["counts"]["particles_removed"] == 0 and np.all(v < 0), "recycled downward flow")
    print(f"mass_flow_rate {m['mass_flow_rate']:.4f} kg/s, <v> {np.round(v, 4)}, beta {m['beta_below_slit']:.3f}, "
          f"particle_steps_per_s {m['particle_steps_per_s']:.3g}")


def curtain_full():
    """Long validation run (label validate): the full-size curtain of 002 §3.4."""
    out, s = run_case("curtain")
    beta = s["metrics"]["beta_below_slit"]
    expect(0.45 <= beta <= 0.64, f"beta below the slit {beta:.3f}")
    subprocess.run([sys.executable, os.path.join(SOURCE, "postprocess", "plot_dem_profiles.py"),
                    os.path.join(out, "curtain_state.h5")], check=True)


if __name__ == "__main__":
    main({f.__name__: f for f in [collision_restitution_linear, collision_energy_drift,
                                  collision_laws_on_1_and_2_ranks, settled_bed_packing,
                                  restart_bitwise_with_history, hopper_drain_flow_rate,
                                  hopper_drain_on_2_ranks, curtain_small_state,
                                  channel_small_plug_flow, channel_full, curtain_full,
                                  hopper_restart_bitwise, dense_bed_on_1_and_2_ranks,
                                  slabs_follow_a_settling_bed, neighbour_list_against_cell_search,
                                  rough_hopper_walls]})
