"""The command line: bad input exits 2 with file:line:key, and nothing is written."""
import os
import re

from gwtest import case, expect, grainwave, main, scratch

DEMO = open(case("demo.toml")).read()


def write_scene(folder, text, name="scene.toml"):
    path = os.path.join(folder, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def expect_input_error(args, pattern, what):
    proc = grainwave(*args)
    expect(proc.returncode == 2, f"{what}: exit code 2 (got {proc.returncode})")
    expect(re.search(pattern, proc.stderr) is not None,
           f"{what}: message matches {pattern!r}: {proc.stderr.strip()}")


def misspelt_key():
    d = scratch("misspelt_key")
    text = DEMO.replace("t_end = 2.0", "t_edn = 2.0")
    line = text.splitlines().index("t_edn = 2.0") + 1
    scene = write_scene(d, text)
    expect_input_error(["check", scene],
                       rf"{re.escape(scene)}:{line}: key 'run\.t_edn': unknown key in \[run\] "
                       r"\(did you mean 'run\.t_end'\?\)", "misspelt key")


def wrong_type():
    d = scratch("wrong_type")
    scene = write_scene(d, DEMO.replace("count = 2000", "count = 2000.5"))
    expect_input_error(["check", scene], r"scene\.toml:\d+: key 'particles\.count': expected "
                       r"integer, got real", "wrong type")


def out_of_range():
    d = scratch("out_of_range")
    scene = write_scene(d, DEMO.replace("radius = 0.2", "radius = -0.2"))
    expect_input_error(["check", scene], r"key 'particles\.radius': value -0\.2 is out of range",
                       "out of range")
    expect_input_error(["check", case("demo.toml"), "--set", "run.dt=-1"],
                       r"--set run\.dt=-1: key 'run\.dt': value -1 is out of range",
                       "out of range from --set")


def missing_required():
    d = scratch("missing_required")
    scene = write_scene(d, DEMO.replace("t_end = 2.0\n", ""))
    expect_input_error(["check", scene], r"key 'run\.t_end': required key is missing",
                       "missing required key")


def malformed_toml():
    d = scratch("malformed")
    scene = write_scene(d, DEMO.replace("dt = 0.01", "dt = = 0.01"))
    expect_input_error(["check", scene], r"scene\.toml:\d+: malformed TOML", "malformed TOML")


def unreadable_file():
    expect_input_error(["check", "/nonexistent/scene.toml"],
                       r"/nonexistent/scene\.toml: cannot read scene file", "unreadable file")
    d = scratch("unreadable_h5")
    bogus = write_scene(d, "not hdf5", name="bogus.h5")
    expect_input_error(["info", bogus], r"bogus\.h5: not an HDF5 file", "info on a non-HDF5 file")


def unwritable_output():
    d = scratch("unwritable")
    blocker = write_scene(d, "a file, not a folder", name="blocker")
    out = os.path.join(blocker, "run")
    expect_input_error(["run", case("demo.toml"), "--out", out], r"key '--out': cannot create "
                       "output folder", "output folder that cannot be written")
    expect(os.listdir(d) == ["blocker"], "nothing else was written")


def nothing_written_on_bad_input():
    d = scratch("nothing_written")
    out = os.path.join(d, "out")
    grainwave("run", case("demo.toml"), "--set", "particles.count=-5", "--out", out)
    expect(not os.path.exists(out), "a scene error writes no output folder")


def bad_command_line():
    proc = grainwave("run")
    expect(proc.returncode == 2, f"missing scene argument exits 2 (got {proc.returncode})")
    proc = grainwave("frobnicate")
    expect(proc.returncode == 2, "unknown verb exits 2")
    expect(grainwave("--version").stdout.startswith("grainwave "), "--version prints the version")
    for verb in ["run", "check", "info", "reference"]:
        proc = grainwave(verb, "--help")
        expect(proc.returncode == 0 and "Usage" in proc.stdout, f"{verb} --help")


def check_prints_resolution():
    proc = grainwave("check", case("demo.toml"), check=0)
    for needle in ["time step  0.01 from run.dt", "memory", "[particles]", "(default)",
                   "builds"]:
        expect(needle in proc.stdout, f"check output shows {needle!r}")


def all_cases_validate():
    cases_dir = os.path.join(os.path.dirname(case("demo.toml")))
    for name in sorted(os.listdir(cases_dir)):
        if name.endswith(".toml"):
            proc = grainwave("check", os.path.join(cases_dir, name))
            expect(proc.returncode == 0, f"cases/{name} validates: {proc.stderr.strip()}")


def scene_reference_up_to_date():
    generated = grainwave("reference", check=0).stdout
    path = os.path.join(os.path.dirname(case("demo.toml")), "..", "docs", "scene-reference.md")
    with open(path) as f:
        committed = f.read()
    expect(generated == committed, "docs/scene-reference.md matches the parameter declarations "
           "(regenerate: build/app/grainwave reference > docs/scene-reference.md)")


main({f.__name__: f for f in [misspelt_key, wrong_type, out_of_range, missing_required,
                               malformed_toml, unreadable_file, unwritable_output,
                               nothing_written_on_bad_input, bad_command_line,
                               check_prints_resolution, all_cases_validate,
                               scene_reference_up_to_date]})
