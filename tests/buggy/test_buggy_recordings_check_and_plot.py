"""`iotad check` finds no violation in a Buggy recording; `iotad plot` draws it (Figures 4/5);
a bad body parameter is a clear error before anything runs."""
import subprocess

from buggy_runs import IOTAD, ROOT


def test_iotad_check_passes(buggy_run):
    done = subprocess.run([IOTAD, "check", str(buggy_run)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr
    assert "every node conforms to its spec" in done.stdout


def test_iotad_plot_draws_the_arena_and_moods(buggy_run, tmp_path):
    picture = tmp_path / "buggy.png"
    done = subprocess.run([IOTAD, "plot", str(buggy_run), "-o", str(picture)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert picture.stat().st_size > 20_000


def test_a_bad_body_parameter_is_named(tmp_path):
    text = (ROOT / "examples" / "buggy.toml").read_text().replace("sense_period = 0.1", "sense_period = -1")
    system = ROOT / "examples" / "buggy" / ".." / "buggy.toml"
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('"buggy/', f'"{system.parent.resolve()}/buggy/'))
    done = subprocess.run([IOTAD, "run", "--check", str(bad)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert "sense_period must be a number > 0" in done.stdout + done.stderr
    assert "Traceback" not in done.stdout + done.stderr


def test_replaying_a_composite_node_names_its_parts(buggy_run):
    # `conscious` is one process in real time; a virtual run records its three parts one by one
    done = subprocess.run([IOTAD, "replay", str(buggy_run), "--node", "conscious"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2
    assert ("'conscious' is a composite whose parts this recording holds one by one: replay each "
            "(--node conscious/c, --node conscious/f, --node conscious/w)") in done.stderr
    part = subprocess.run([IOTAD, "replay", str(buggy_run), "--node", "conscious/c"], capture_output=True, text=True,
                          timeout=120)
    assert part.returncode == 0 and "conscious/c: replay agrees" in part.stdout
