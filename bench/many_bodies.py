#!/usr/bin/env python3
"""What immersed bodies cost as their number grows: the two-cylinder scene
(cases/two_cylinders.toml) with an n x n array of moving cylinders (D = 1, 2.5 D apart, speed 0.3
along x) in place of its two, for a few steps. Prints, per n, the blocks and the seconds of the
parts that visit bodies: the masks (`penalization`, and `forces`, which updates them before it
measures) and the forced region (in `adapt`), next to the right-hand side's. Until stop 48 both
tested every body for every block, so they grew with the square of the number of bodies.

usage: bench/many_bodies.py GRAINWAVE_EXECUTABLE [OUT_FOLDER] [--sides=2,4,8] [--steps=8]
"""
import json
import os
import subprocess
import sys

SOURCE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def scene(side):
    """cases/two_cylinders.toml with side x side cylinders around the middle of its domain."""
    with open(os.path.join(SOURCE, "cases", "two_cylinders.toml")) as f:
        text = f.read()
    text = text[:text.index("[[body]]")]
    start = 24.0 - 1.25 * (side - 1)
    for i in range(side):
        for k in range(side):
            text += (f'\n[[body]]\nshape = "cylinder"\ncentre = [{start + 2.5 * i}, {start + 2.5 * k}, 0.0]\n'
                     f"radius = 0.5\nvelocity = [0.3, 0.0, 0.0]\n")
    return text


def option(name, default):
    return next((a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith(f"--{name}=")), default)


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if not args:
        sys.exit(__doc__)
    exe = args[0]
    out = args[1] if len(args) > 1 else "out/many_bodies"
    sides = [int(s) for s in option("sides", "2,4,8").split(",")]
    steps = option("steps", "8")
    os.makedirs(out, exist_ok=True)
    print(f"{'bodies':>7s} {'blocks':>7s} {'steps':>6s} {'penalization':>13s} {'forces':>8s} {'adapt':>8s} "
          f"{'RHS':>8s} {'wall':>8s}   (seconds)")
    for side in sides:
        folder = os.path.join(out, f"bodies_{side * side}")
        os.makedirs(folder, exist_ok=True)
        path = os.path.join(folder, "scene.toml")
        with open(path, "w") as f:
            f.write(scene(side))
        subprocess.run([exe, "-q", "run", path, "--out", folder, "--set", f"run.max_steps={steps}", "--set", "output.interval=0"],
                       check=True, capture_output=True, text=True)
        with open(os.path.join(folder, "summary.json")) as f:
            s = json.load(f)
        t = s["timings_s"]
        rhs = sum(v for k, v in t.items() if k.startswith("rhs: "))
        print(f"{side * side:7d} {s['counts']['blocks']:7d} {s['steps']:6d} {t.get('penalization', 0):13.3f} "
              f"{t.get('forces', 0):8.3f} {t.get('adapt', 0):8.3f} {rhs:8.3f} {s['wall_s']:8.2f}")


if __name__ == "__main__":
    main()
