"""The default demo scene runs and its summary.json holds what users' scripts read."""
from gwtest import case, expect, grainwave, main, scratch, summary


def demo_runs():
    out = scratch("demo")
    grainwave("run", case("demo.toml"), "--out", out, check=0)
    s = summary(out)
    for key in ["scene", "scene_sha256", "version", "ranks", "steps", "t_final", "wall_s",
                "counts", "timings_s", "metrics"]:
        expect(key in s, f"summary.json has '{key}'")
    expect(s["status"] == "completed" and s["steps"] == 200 and s["t_final"] == 2.0,
           f"200 steps to t = 2 ({s['steps']}, {s['t_final']})")
    c = s["counts"]
    expect(c["particles"] + c["particles_removed"] == 2000,
           f"every particle is either in the box or counted as removed ({c})")
    # Free fall from z <= 20 under g = 9.81: after 2 s a particle has dropped >= 19.6 unless it
    # started moving up fast, so most have left through the open floor.
    expect(c["particles_removed"] > 1500, "most particles fell out of the open floor")
    expect(s["metrics"]["particle_steps_per_s"] > 0, "throughput is reported")


main({"demo_runs": demo_runs})
