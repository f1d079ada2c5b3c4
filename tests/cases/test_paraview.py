"""The XDMF written by a run opens in ParaView (pvpython) with the right points and arrays."""
import os
import shutil
import subprocess

from gwtest import SKIP, case, expect, grainwave, main, scratch, summary

PV_SCRIPT = r"""
import sys
from paraview.simple import XDMFReader
reader = XDMFReader(FileNames=[sys.argv[1]])
reader.UpdatePipelineInformation()
times = list(reader.TimestepValues)
reader.UpdatePipeline(times[-1])
info = reader.GetDataInformation()
print("points", info.GetNumberOfPoints())
print("arrays", ",".join(sorted(reader.PointData.keys())))
print("steps", len(times))
"""


def particles_xdmf_opens():
    pvpython = shutil.which("pvpython")
    if not pvpython:
        print("SKIPPED: pvpython not found; install ParaView with `scripts/setup --paraview`")
        return SKIP
    out = scratch("paraview")
    grainwave("run", case("demo.toml"), "--set", "run.t_end=0.5", "--out", out, check=0)
    script = os.path.join(out, "load.py")
    with open(script, "w") as f:
        f.write(PV_SCRIPT)
    proc = subprocess.run([pvpython, "--force-offscreen-rendering", script,
                           os.path.join(out, "particles.xmf")],
                          capture_output=True, text=True, timeout=300)
    print(proc.stdout, proc.stderr)
    values = dict(line.split(" ", 1) for line in proc.stdout.splitlines() if " " in line)
    expect(proc.returncode == 0, "pvpython loaded particles.xmf")
    expected = summary(out)["counts"]["particles"]
    expect(int(values.get("points", -1)) == expected,
           f"{values.get('points')} points = {expected} particles at the last step")
    expect(values.get("arrays") == "angular_velocity,id,radius,velocity",
           f"point arrays {values.get('arrays')}")
    expect(int(values.get("steps", 0)) == 6, f"6 time steps in the series ({values.get('steps')})")


main({"particles_xdmf_opens": particles_xdmf_opens})
