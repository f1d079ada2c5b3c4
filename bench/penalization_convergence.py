#!/usr/bin/env python3
"""Convergence of the characteristic-based Brinkman penalization in its parameters: the error
should behave as O(eta_c, eta_b^1/2) (Brown-Dymkoski, Kasimov & Vasilyev 2014; 002 §2.4.1),
plus the grid's own error (the mask's smoothing width is tied to the finest spacing h).

Measured on cases/shock_reflection_penalized.toml (Ms = 1.66, 1D): the position of the shock
reflected from the penalized wall, from the pressure integral over the gas side
(reflected_shock_distance in summary.json), against the exact W_r (t - t_hit). Gas penetrating
the wall (eta_b) and a lagging extension of the wall values into the body (eta_c) both move it.

Each study varies one parameter with the others small, and prints the error and the observed
order between successive runs, both against the exact position and, where the other error
sources leave a floor, from successive differences (Richardson: the order of d_k = x_k - x_{k+1}
for a parameter halved or divided by ten each time).

usage: bench/penalization_convergence.py GRAINWAVE_EXECUTABLE [OUT_FOLDER]
"""
import json
import math
import os
import subprocess
import sys

SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(exe, out, settings):
    cmd = [exe, "run", os.path.join(SOURCE, "cases", "shock_reflection_penalized.toml"), "--out", out, "-q",
           "--set", "output.interval=0"]
    for s in settings:
        cmd += ["--set", s]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    with open(os.path.join(out, "summary.json")) as f:
        m = json.load(f)["metrics"]
    return m["reflected_shock_distance"], m["reflected_shock_distance_exact"], m["p_reflected_relative_error"]


def study(exe, out, name, values, fixed, expected, size=lambda v: v):
    """size(v): the magnitude the error should scale with (the value itself, or h for a level)."""
    print(f"\n{name} (others: {', '.join(fixed)}); expected order {expected}")
    print(f"{name:>10} {'distance':>12} {'|error|':>10} {'order':>6} {'d_k':>10} {'order(d)':>8} {'p5 err':>9}")
    rows = []
    for v in values:
        x, exact, p_err = run(exe, os.path.join(out, f"{name}_{v}"), fixed + [f"{name if '.' in name else 'penalization.' + name}={v}"])
        rows.append((v, x, abs(x - exact), p_err))
    for k, (v, x, err, p_err) in enumerate(rows):
        order = diff_order = ""
        diff = rows[k][1] - rows[k + 1][1] if k + 1 < len(rows) else None
        if k > 0:
            ratio = size(rows[k - 1][0]) / size(v)
            order = f"{math.log(rows[k - 1][2] / err) / math.log(ratio):6.2f}" if err > 0 else ""
            if diff is not None:
                previous = rows[k - 1][1] - x
                if diff != 0 and previous / diff > 0:
                    diff_order = f"{math.log(previous / diff) / math.log(ratio):8.2f}"
        print(f"{v:>10} {x:12.6f} {err:10.3e} {order:>6} {diff if diff is not None else float('nan'):10.3e} "
              f"{diff_order:>8} {p_err:9.2e}")
    return rows


def main():
    exe = sys.argv[1]
    out = sys.argv[2] if len(sys.argv) > 2 else "out/penalization_convergence"
    os.makedirs(out, exist_ok=True)
    study(exe, out, "eta_b", [1e-2, 1e-3, 1e-4], ["penalization.eta_c=0.05"], "1/2")
    study(exe, out, "eta_c", [2.0, 1.0, 0.5, 0.25, 0.125], ["penalization.eta_b=1e-5"], "1")
    study(exe, out, "fluid.max_level", [5, 6, 7, 8], ["penalization.eta_b=1e-5", "penalization.eta_c=0.05"],
          "1 (smoothing width ~ h)", size=lambda level: 2.0 ** -level)


if __name__ == "__main__":
    main()
