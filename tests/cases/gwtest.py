"""Shared helpers for grainwave's command-level tests (run by CTest).

Each test script is called as  python3 SCRIPT TEST_NAME  with the environment set by CTest:
GRAINWAVE (the executable), GRAINWAVE_SOURCE (the source tree), GRAINWAVE_MPIEXEC (the MPI
launcher, space separated) and GRAINWAVE_WORK (a scratch folder for this test).
Exit code 0 passes, 77 skips (with a message saying why), anything else fails.
"""
import json
import math
import os
import shutil
import subprocess
import sys

EXE = os.environ["GRAINWAVE"]
SOURCE = os.environ["GRAINWAVE_SOURCE"]
MPIEXEC = os.environ.get("GRAINWAVE_MPIEXEC", "mpirun").split()
WORK = os.environ["GRAINWAVE_WORK"]
SKIP = 77


def scratch(name):
    """A fresh, empty folder for one test."""
    path = os.path.join(WORK, name)
    shutil.rmtree(path, ignore_errors=True)
    os.makedirs(path)
    return path


def case(name):
    return os.path.join(SOURCE, "cases", name)


# The whole test's time limit (set by CTest, scaled under the sanitizers); one command may use
# all of it, and CTest stops the test as a whole when it runs out.
TEST_TIMEOUT = float(os.environ.get("GRAINWAVE_TEST_TIMEOUT", "600"))


def grainwave(*args, ranks=None, check=None, timeout=None):
    """Runs grainwave (under MPI when ranks is given); returns the CompletedProcess."""
    timeout = timeout or TEST_TIMEOUT
    cmd = ([*MPIEXEC, "-np", str(ranks)] if ranks else []) + [EXE, *args]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if check is not None and proc.returncode != check:
        fail(f"{' '.join(cmd)} exited {proc.returncode}, expected {check}\n"
             f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}")
    return proc


def run_scene(name, *settings, ranks=None, check=0, out=None):
    """Runs cases/NAME with `--set` settings into OUT (default: a scratch folder named after the
    case); returns (summary.json, the folder, the CompletedProcess)."""
    out = out or scratch(name.replace(".toml", ""))
    sets = [item for s in settings for item in ("--set", s)]
    proc = grainwave("run", case(name), *sets, "--out", out, ranks=ranks, check=check)
    return summary(out), out, proc


def summary(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        return json.load(f)


def fail(message):
    print("FAIL:", message)
    sys.exit(1)


def expect(condition, message):
    if not condition:
        fail(message)
    print("ok:", message)


def main(tests):
    """Runs the test named on the command line from the dict name -> function."""
    name = sys.argv[1]
    if name not in tests:
        fail(f"no test {name}; have {sorted(tests)}")
    result = tests[name]()
    sys.exit(result or 0)


def read_points(folder, *fields):
    """x, y and the named fields at every point of a 2D output's last file (XDMF block geometry)."""
    import glob
    import xml.etree.ElementTree as ElementTree

    import h5py
    import numpy as np
    path = sorted(glob.glob(os.path.join(folder, "output_*.h5")))[-1]
    grids = [g for g in ElementTree.parse(path.replace(".h5", ".fluid.xmf")).getroot().iter("Grid")
             if g.get("GridType") == "Uniform"]
    with h5py.File(path, "r") as f:
        values = [np.array(f["fluid"][k]) for k in fields]
    columns = [[] for _ in range(2 + len(fields))]
    for b, grid in enumerate(grids):
        ny, nx = (int(n) for n in grid.find("Topology").get("Dimensions").split())
        origin, spacing = (list(map(float, item.text.split())) for item in grid.find("Geometry"))  # y, x
        y, x = np.meshgrid(origin[0] + spacing[0] * np.arange(ny), origin[1] + spacing[1] * np.arange(nx), indexing="ij")
        columns[0].append(x.ravel())
        columns[1].append(y.ravel())
        for k, v in enumerate(values):
            columns[2 + k].append(v[b])
    return [np.concatenate(c) for c in columns]


def profile_along_y(folder, field, x=0.0):
    """(y, value) of a 2D output's field on the grid line x = const."""
    import numpy as np
    xs, ys, values = read_points(folder, field)
    on_line = np.abs(xs - x) < 1e-12
    order = np.argsort(ys[on_line])
    return np.column_stack([ys[on_line][order], values[on_line][order]])


def erf_inverse(z):
    """The inverse error function, by bisection."""
    lo, hi = -6.0, 6.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.erf(mid) < z else (lo, mid)
    return 0.5 * (lo + hi)


def fitted_wall(y, ratio, diffusivity, t):
    """Wall positions fitted point by point to ratio = erf((y - y_w) / 2 sqrt(diffusivity t)), from
    the points with 0.15 < ratio < 0.85."""
    return [yy - 2 * math.sqrt(diffusivity * t) * erf_inverse(r) for yy, r in zip(y, ratio) if 0.15 < r < 0.85]
