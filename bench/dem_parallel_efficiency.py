#!/usr/bin/env python3
"""2-rank parallel efficiency of the domain-decomposed DEM (issue 7's target: >= 80 %).

Runs build/bench/bench_dem_ranks on 1 and on 2 ranks (the same 20 384-sphere flowing bed),
prints both lines and the efficiency T1 / (2 T2) per tangential law. Usage:
    python3 bench/dem_parallel_efficiency.py [steps] [--mpiexec "mpirun --oversubscribe"]
"""
import argparse
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run(mpiexec, ranks, steps, exe):
    cmd = [*mpiexec.split(), "-np", str(ranks), exe, str(steps)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    print(out, end="")
    return {m.group(1): float(m.group(2))
            for m in re.finditer(r"^(\S+)\s+ranks \d+\s+(\S+) particle-steps/s", out, re.M)}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("steps", nargs="?", type=int, default=300)
    default = "mpirun --oversubscribe" + (" --allow-run-as-root" if os.geteuid() == 0 else "")
    parser.add_argument("--mpiexec", default=default)
    parser.add_argument("--exe", default=os.path.join(ROOT, "build", "bench", "bench_dem_ranks"))
    args = parser.parse_args()
    one = run(args.mpiexec, 1, args.steps, args.exe)
    two = run(args.mpiexec, 2, args.steps, args.exe)
    for law in one:
        efficiency = two[law] / (2 * one[law])
        print(f"{law:<16} 2-rank parallel efficiency {100 * efficiency:5.1f} %  (target 80 %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
