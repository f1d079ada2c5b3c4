#!/usr/bin/env python3
"""Run time against error for the fluid solver: Sod (t = 0.2, up to L10 = 16384 points) and the
isentropic vortex (t = 1; in its 10 x 10 box and in a 40 x 40 one) on uniform grids of
increasing resolution and on adaptive grids with eps = 1e-2 ... 1e-5 (the vortex also 1e-6) at
the finest level of the largest uniform grid. Writes one table (case, grid, eps, points computed, wall time, L1 density
error) as runtime_vs_error.csv and .md into the output folder, then the adaptive runs' wall time
over the uniform grids' at the same error (issue 4: at most 1/5 for Sod, 1/10 for the 2D cases);
plot it with postprocess/runtime_vs_error.py.

usage: bench/runtime_vs_error.py GRAINWAVE_EXECUTABLE [OUT_FOLDER] [--quick]
Point counts are point-RHS evaluations (points x RHS calls summed over steps), the work actually
done; wall time is the run's wall_s (one rank, output only at start and end).
"""
import csv
import json
import math
import os
import subprocess
import sys

SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# Thresholds of the adaptive runs. Sod's error is first order (its discontinuities): at eps 1e-4
# it is already the finest uniform grid's. The vortex's is 4th order: at L4 its adaptive runs come
# within a few tens of percent of the uniform L4 error only at eps 1e-6 (at 1e-5 it is 2.7 times
# that), so its range goes one decade further than issue 4's 1e-2 ... 1e-5.
SOD_EPS = (1e-2, 1e-3, 1e-4, 1e-5)
VORTEX_EPS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)


def run(exe, scene, out, settings):
    cmd = [exe, "run", os.path.join(SOURCE, "cases", scene), "--out", out, "--set", "output.interval=0"]
    for s in settings:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    quick = "--quick" in sys.argv
    exe = args[0]
    out = args[1] if len(args) > 1 else "out/runtime_vs_error"
    os.makedirs(out, exist_ok=True)
    studies = [
        # Sod up to 16384 points (L10): 1D runs are cheap. The adaptive points fraction falls with
        # the finest level, but at a fixed eps the error does not (eps sets it) while the steps
        # double per level: the ratio at L12 was no better than at L10 (stop 35's note).
        ("sod", "sod.toml", [], range(3, 6 if quick else 11), 5 if quick else 10, SOD_EPS),
        ("vortex", "isentropic_vortex.toml", ["run.t_end=1", "fluid.shock_capturing=false"], range(1, 4 if quick else 5),
         3 if quick else 4, VORTEX_EPS),
        # The same vortex, same spacings, in a periodic box 4 times wider (16 times the area): the
        # vortex then covers a few percent of the domain, as localised features do in the flows
        # the adaptive grid is for; in the 10 x 10 box it covers 20-67% (points_fraction).
        ("vortex_box40", "isentropic_vortex.toml",
         ["run.t_end=1", "fluid.shock_capturing=false", "fluid.hi=[40.0,40.0,1.0]", "fluid.roots=[4,4,1]",
          "fluid.centre=[20.0,20.0,0.0]"], range(1, 4 if quick else 5), 3 if quick else 4, VORTEX_EPS),
    ]
    rows = []
    for name, scene, common, levels, finest, epsilons in studies:
        for level in levels:
            s = run(exe, scene, os.path.join(out, f"{name}_uniform_{level}"),
                    common + ["fluid.adaptive=false", f"fluid.max_level={level}"])
            rows.append((name, f"uniform L{level}", "", s))
        for eps in epsilons:
            s = run(exe, scene, os.path.join(out, f"{name}_adaptive_{eps:.0e}"),
                    common + [f"fluid.max_level={finest}", f"fluid.epsilon={eps}"])
            rows.append((name, f"adaptive L{finest}", f"{eps:.0e}", s))
    table = []
    for name, grid, eps, s in rows:
        per_block = s["counts"]["points"] / s["counts"]["blocks"]
        work = s["metrics"]["point_rhs_per_s"] * s["wall_s"]  # approximate: rate is per stepping second
        table.append({"case": name, "grid": grid, "eps": eps, "final_points": s["counts"]["points"],
                      "points_fraction": f"{s['metrics']['points_fraction']:.3f}",
                      "point_rhs": f"{work:.3e}", "wall_s": f"{s['wall_s']:.3f}",
                      "L1_rho": f"{s['metrics']['L1_rho']:.3e}", "block_points": int(per_block)})
    with open(os.path.join(out, "runtime_vs_error.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    with open(os.path.join(out, "runtime_vs_error.md"), "w") as f:
        keys = list(table[0])
        f.write("| " + " | ".join(keys) + " |\n|" + " --- |" * len(keys) + "\n")
        for r in table:
            f.write("| " + " | ".join(str(r[k]) for k in keys) + " |\n")
    print(open(os.path.join(out, "runtime_vs_error.md")).read())
    print(speedups(table))


def speedups(table):
    """Issue 4's targets: at equal L1 error, the adaptive run's wall time against the uniform
    grids' (log-log interpolation between the two uniform runs that bracket its error; none
    when the error is outside the uniform range)."""
    lines = ["| case | eps | L1_rho | adaptive wall_s | uniform wall_s at that error | ratio |",
             "| --- | --- | --- | --- | --- | --- |"]
    for name in sorted({r["case"] for r in table}):
        uniform = sorted(((float(r["L1_rho"]), float(r["wall_s"])) for r in table
                          if r["case"] == name and r["grid"].startswith("uniform")), reverse=True)
        for r in table:
            if r["case"] != name or not r["grid"].startswith("adaptive"):
                continue
            error, wall = float(r["L1_rho"]), float(r["wall_s"])
            at = None
            for (e0, t0), (e1, t1) in zip(uniform, uniform[1:]):
                if e1 <= error <= e0 and e0 > e1:
                    w = math.log(error / e0) / math.log(e1 / e0)
                    at = math.exp(math.log(t0) + w * (math.log(t1) - math.log(t0)))
            lines.append(f"| {name} | {r['eps']} | {error:.3e} | {wall:.3f} | "
                         + (f"{at:.3f} | {wall / at:.3f} |" if at else "— | — |"))
    return "\n".join(lines)


if __name__ == "__main__":
    main()
