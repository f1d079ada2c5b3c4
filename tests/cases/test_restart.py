"""A run killed with SIGKILL leaves no truncated file under a final name, and restarting from its
last checkpoint reproduces the uninterrupted run's final state bit for bit."""
import glob
import os

import h5py
import numpy as np

from gwtest import case, expect, fail, grainwave, main, scratch

SETTINGS = ["--set", "run.t_end=1.0", "--set", "output.interval=0.1",
            "--set", "output.checkpoint_every_steps=20", "--set", "particles.count=500"]


def final_particles(folder):
    last = sorted(glob.glob(os.path.join(folder, "output_*.h5")))[-1]
    with h5py.File(last, "r") as f:
        return last, {k: np.array(f["particles"][k]) for k in f["particles"]}, f.attrs["time"]


def every_final_h5_is_complete(folder):
    for path in glob.glob(os.path.join(folder, "*.h5")):
        try:
            with h5py.File(path, "r") as f:
                list(f.keys())
        except OSError as e:
            fail(f"{path} is under a final name but is not a readable HDF5 file: {e}")
    print(f"ok: all {len(glob.glob(os.path.join(folder, '*.h5')))} final .h5 files are readable")


def killed_then_restarted(kill_during):
    reference = scratch(f"restart_reference_{kill_during}")
    grainwave("run", case("demo.toml"), *SETTINGS, "--out", reference, check=0)
    killed = scratch(f"restart_killed_{kill_during}")
    proc = grainwave("run", case("demo.toml"), *SETTINGS, "--set", "debug.kill_at_step=80",
                     "--set", f"debug.kill_during={kill_during}", "--out", killed)
    expect(proc.returncode in (-9, 137), f"run killed by SIGKILL at step 80 (rc {proc.returncode})")
    tmp = glob.glob(os.path.join(killed, "*.tmp"))
    expect(len(tmp) == 1, f"the file being written when killed is only under its temporary name: "
           f"{[os.path.basename(t) for t in tmp]}")
    expect(not os.path.exists(os.path.join(killed, "summary.json")), "no summary of a killed run")
    every_final_h5_is_complete(killed)
    grainwave("run", case("demo.toml"), *SETTINGS, "--restart", killed, check=0)
    name_a, a, time_a = final_particles(reference)
    name_b, b, time_b = final_particles(killed)
    expect(os.path.basename(name_a) == os.path.basename(name_b) and time_a == time_b,
           f"same final output file {os.path.basename(name_a)} at t = {time_a}")
    for key in a:
        expect(np.array_equal(a[key], b[key]), f"particles/{key} identical after restart")
    with open(os.path.join(killed, "particles.xmf")) as f:
        steps = f.read().count("<Time ")
    expect(steps == 11, f"the restarted run's XDMF series holds all 11 outputs (has {steps})")


def kill_during_output():
    killed_then_restarted("output")


def kill_during_checkpoint():
    killed_then_restarted("checkpoint")


main({"kill_during_output": kill_during_output, "kill_during_checkpoint": kill_during_checkpoint})
