#!/usr/bin/env python3
"""Compares builds of a Google Benchmark program on a shared machine, where other tenants' load
moves a memory-bound benchmark by 20-50% from one minute to the next: the builds run in
alternating rounds (each round every build in turn, so a quiet or a loaded phase falls on all of
them), and each build's repetitions are pooled. Prints, per build, the best, the 90th percentile
and the median of one counter (a rate: higher is better) or, without a counter, of the real time
(lower is better).

usage: bench/compare_builds.py [--rounds=N] [--repetitions=N] [--counter=NAME] FILTER BENCH...
  e.g. bench/compare_builds.py --counter=collisions/s "EventDriven/97556" old/bench_hardsphere build/bench/bench_hardsphere
"""
import re
import statistics
import subprocess
import sys

UNITS = {"": 1.0, "k": 1e3, "M": 1e6, "G": 1e9}
TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}


def option(name, default):
    for a in sys.argv[1:]:
        if a.startswith(f"--{name}="):
            return a.split("=", 1)[1]
    return default


def whole(name, text):
    if not text.isdigit() or int(text) < 1:
        print(f"bench/compare_builds.py: --{name} needs a positive whole number, not '{text}'", file=sys.stderr)
        sys.exit(2)
    return int(text)


def samples(bench, benchmark_filter, repetitions, counter):
    """One value per repetition (aggregate rows left out)."""
    out = subprocess.run([bench, f"--benchmark_filter={benchmark_filter}", f"--benchmark_repetitions={repetitions}"],
                         capture_output=True, text=True, check=True).stdout
    values = []
    for line in out.splitlines():
        if re.search(r"_(mean|median|stddev|cv)\b", line) or not line.startswith("BM_"):
            continue
        if counter:
            m = re.search(re.escape(counter) + r"=([0-9.eE+-]+)([kMG]?)", line)
            if m:
                values.append(float(m.group(1)) * UNITS[m.group(2)])
        else:
            m = re.match(r"\S+\s+([0-9.]+) (ns|us|ms|s)\b", line)
            if m:
                values.append(float(m.group(1)) * TIME_UNITS[m.group(2)])
    if not values:
        print(f"bench/compare_builds.py: {bench} printed no {counter or 'time'} for '{benchmark_filter}'", file=sys.stderr)
        sys.exit(2)
    return values


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) < 2:
        sys.exit(__doc__)
    rounds = whole("rounds", option("rounds", "4"))
    repetitions = whole("repetitions", option("repetitions", "5"))
    counter = option("counter", "")
    benchmark_filter, benches = args[0], args[1:]
    pooled = {b: [] for b in benches}
    for _ in range(rounds):
        for b in benches:
            pooled[b] += samples(b, benchmark_filter, repetitions, counter)
    higher_is_better = bool(counter)
    what = counter or "real time (s)"
    print(f"{what}, {rounds} alternating rounds of {repetitions} repetitions per build")
    print(f"{'build':50s} {'best':>12s} {'90th pct':>12s} {'median':>12s}")
    for b in benches:
        v = sorted(pooled[b], reverse=higher_is_better)  # best first
        print(f"{b[-50:]:50s} {v[0]:12.5g} {v[int(0.1 * (len(v) - 1))]:12.5g} {statistics.median(v):12.5g}")


if __name__ == "__main__":
    main()
