#!/usr/bin/env python3
"""Convergence of the characteristic-based Brinkman penalization in its parameters: the error
should behave as O(eta_c, eta_b^1/2) (Brown-Dymkoski, Kasimov & Vasilyev 2014; 002 §2.4.1),
plus the grid's own error (the mask's smoothing width is tied to the finest spacing h).

Two 1D probes, both with an exact answer:
- cases/shock_reflection_penalized.toml (Ms = 1.66): the position of the shock reflected from the
  penalized wall, from the pressure integral over the gas side (reflected_shock_distance in
  summary.json), against the exact W_r (t - t_hit). Gas penetrating the wall (eta_b) and a
  lagging extension of the wall values into the body (eta_c) both move it.
- cases/acoustic_reflection_penalized.toml: a sound pulse reflected from the penalized wall; the
  shift of its centroid against the exact mirror image (reflected_pulse_shift; h = 1/1024 at
  level 6), and its L2 pressure error over the pulse amplitude. The wall state changes
  smoothly here, unlike behind a shock.

Each study varies one parameter with the others small, and prints the error and the observed
order between successive runs, both against the exact answer and, where the other error sources
leave a floor, from successive differences (Richardson: the order of d_k = x_k - x_{k+1} for a
parameter halved or divided by ten each time).

Why eta_c runs down to 1/512: the O(eta_c) is asymptotic. With a smoothed mask the grid points
at the band's onset have a small chi (0.045 here), where the Brinkman term already holds u = 0;
the characteristic transport, weighted by chi, runs there at only chi / eta_c, and until eta_c c
is well below that chi the wall values reach those points late: orders 0.5-0.8 (stop 12's 0.8
on eta_c = 2 ... 0.125), approaching 1 only below eta_c ~ 1/64. The last eta_c study repeats the
pulse with [penalization] characteristic_gain = 30 (weight min(1, 30 chi), fluid/Penalization.hpp),
which removes that lag.

usage: bench/penalization_convergence.py GRAINWAVE_EXECUTABLE [OUT_FOLDER] [--quick]
  --quick: the eta_c studies only down to 1/128 (about two minutes instead of nine)
"""
import json
import math
import os
import subprocess
import sys
import tomllib

SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHOCK = "shock_reflection_penalized.toml"
PULSE = "acoustic_reflection_penalized.toml"


def run(exe, case, out, settings):
    cmd = [exe, "run", os.path.join(SOURCE, "cases", case), "--out", out, "-q", "--set", "output.interval=0"]
    for s in settings:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)["metrics"]


def shock_position(m):
    """Signed value, its exact value, and a side column (p5/p1 relative error)."""
    return m["reflected_shock_distance"], m["reflected_shock_distance_exact"], m["p_reflected_relative_error"]


def pulse_amplitude():
    """p' = A p of the pulse case, from its scene file."""
    with open(os.path.join(SOURCE, "cases", PULSE), "rb") as f:
        fluid = tomllib.load(f)["fluid"]
    return fluid["pulse_amplitude"] * fluid["left"][2]


def pulse_shift(m):
    """The pulse's shift (exact 0), and its L2 pressure error over the amplitude."""
    return m["reflected_pulse_shift"], 0.0, m["L2_p"] / pulse_amplitude()


def order(previous, current, ratio):
    return math.log(previous / current) / math.log(ratio) if previous > 0 and current > 0 else None


def study(exe, out, case, name, values, fixed, expected, measure, side_name, size=lambda v: v):
    """size(v): the magnitude the error should scale with (the value itself, or h for a level)."""
    key = name if "." in name else "penalization." + name
    print(f"\n{case}: {name} (others: {', '.join(fixed)}); expected order {expected}")
    print(f"{name:>12} {'value':>12} {'|error|':>10} {'order':>6} {'d_k':>10} {'order(d)':>8} {side_name:>9}")
    rows = []
    for v in values:
        folder = os.path.join(out, f"{case[:-5]}_{name}_{v}" + "".join(f"_{f.split('.', 1)[-1]}" for f in fixed))
        value, exact, side = measure(run(exe, case, folder, fixed + [f"{key}={v}"]))
        rows.append((v, value, abs(value - exact), side))
    orders = []
    for k, (v, x, err, side) in enumerate(rows):
        o = od = None
        diff = rows[k][1] - rows[k + 1][1] if k + 1 < len(rows) else None
        if k > 0:
            ratio = size(rows[k - 1][0]) / size(v)
            o = order(rows[k - 1][2], err, ratio)
            if diff is not None and diff != 0:
                od = order((rows[k - 1][1] - x) / diff, 1.0, ratio)
                orders.append(od)
        fmt = lambda q, w: f"{q:{w}.2f}" if q is not None else " " * w
        print(f"{v:>12.6g} {x:12.6f} {err:10.3e} {fmt(o, 6)} {diff if diff is not None else float('nan'):10.3e} "
              f"{fmt(od, 8)} {side:9.2e}")
    return orders


def main():
    args = [a for a in sys.argv[1:] if a != "--quick"]
    quick = "--quick" in sys.argv
    exe = args[0]
    out = args[1] if len(args) > 1 else "out/penalization_convergence"
    os.makedirs(out, exist_ok=True)
    small_eta_c = [2.0 ** -k for k in range(0, 8 if quick else 10)]  # 1 ... 1/128 or 1/512
    summary = {}
    summary["eta_b"] = study(exe, out, SHOCK, "eta_b", [1e-2, 1e-3, 1e-4], ["penalization.eta_c=0.05"], "1/2",
                             shock_position, "p5 err")
    summary["eta_c (shock)"] = study(exe, out, SHOCK, "eta_c", small_eta_c, ["penalization.eta_b=1e-5"], "1",
                                     shock_position, "p5 err")
    summary["eta_c (pulse)"] = study(exe, out, PULSE, "eta_c", small_eta_c, ["penalization.eta_b=1e-7"], "1",
                                     pulse_shift, "L2_p/A")
    summary["eta_c (pulse, gain 30)"] = study(exe, out, PULSE, "eta_c", small_eta_c,
                                              ["penalization.eta_b=1e-7", "penalization.characteristic_gain=30"], "1",
                                              pulse_shift, "L2_p/A")
    # The grid: eta_b at its zero limit (the relaxation is exact, u = 0 wherever chi > 0) and
    # eta_c inside its asymptotic range, so the mask's own O(h) is what is left.
    small = ["penalization.eta_b=1e-9", "penalization.eta_c=0.015625"]
    level = lambda level: 2.0 ** -level
    summary["h (shock)"] = study(exe, out, SHOCK, "fluid.max_level", [4, 5, 6, 7, 8], small, "1 (smoothing width ~ h)",
                                 shock_position, "p5 err", size=level)
    summary["h (pulse)"] = study(exe, out, PULSE, "fluid.max_level", [4, 5, 6, 7, 8], small, "1 (smoothing width ~ h)",
                                 pulse_shift, "L2_p/A", size=level)
    print("\norders from successive differences, in the order of the tables (the h studies' errors against\n"
          "the exact answer are in their tables; differences of a few 1e-7 reach the time step's own floor):")
    for name, orders in summary.items():
        print(f"  {name:>22}: " + ", ".join(f"{o:.2f}" for o in orders if o is not None))


if __name__ == "__main__":
    main()
