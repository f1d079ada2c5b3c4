#!/usr/bin/env python3
"""2-rank parallel efficiency of the domain-decomposed DEM (issue 7's target: >= 80 %).

Runs build/bench/bench_dem_ranks on 1 and on 2 ranks (the same 20 384-sphere flowing bed),
alternately, --repeats times: this machine's speed drifts by tens of per cent over minutes, so
each 2-rank run is compared with the 1-rank runs just before and after it. Prints every line,
the efficiency T1 / (2 T2) of each pair and the median per tangential law. Also prints the
machine's own ceiling: two independent 1-rank runs at once, one per core, against one alone
(memory bandwidth and cache are shared; a perfectly parallel program could not do better).
Usage:
    python3 bench/dem_parallel_efficiency.py [steps] [--repeats 5] [--mpiexec "mpirun ..."]
"""
import statistics
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
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    ones = [run(args.mpiexec, 1, args.steps, args.exe)]
    twos = []
    for _ in range(args.repeats):
        twos.append(run(args.mpiexec, 2, args.steps, args.exe))
        ones.append(run(args.mpiexec, 1, args.steps, args.exe))
    ceilings = []
    for _ in range(max(1, args.repeats // 2)):
        alone = run(args.mpiexec, 1, args.steps, args.exe)
        pair = [subprocess.Popen(["taskset", "-c", str(core), args.exe, str(args.steps)],
                                 stdout=subprocess.PIPE, text=True) for core in (0, 1)]
        outs = [p.communicate()[0] for p in pair]
        together = [{m.group(1): float(m.group(2)) for m in
                     re.finditer(r"^(\S+)\s+ranks \d+\s+(\S+) particle-steps/s", o, re.M)} for o in outs]
        ceilings.append({law: (together[0][law] + together[1][law]) / (2 * alone[law]) for law in alone})
    for law in ones[0]:
        print(f"{law:<16} machine ceiling (2 independent runs at once / 2 x one alone): "
              f"{', '.join(f'{100 * c[law]:.1f}' for c in ceilings)} %")
        pairs = [two[law] / (ones[k][law] + ones[k + 1][law]) for k, two in enumerate(twos)]
        print(f"{law:<16} 2-rank parallel efficiency: median {100 * statistics.median(pairs):5.1f} %  "
              f"(runs: {', '.join(f'{100 * e:.1f}' for e in pairs)}; target 80 %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
