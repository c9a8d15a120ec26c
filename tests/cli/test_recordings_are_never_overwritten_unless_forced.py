"""A recording is the evidence of a run: `iotad run -o` and `iotad record -o` refuse to write over
one (or over a split recording's first member) in one line, before anything starts, and replace it
only with --force. Default names (time-stamped) never collide: a second run in the same second
gets `-2`."""
import subprocess
import sys
from pathlib import Path

from iotad.cli import main
from iotad.launcher.run.recording_paths import unused_recording_path
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = str(ROOT / "examples" / "figure2.toml")


def _run_virtual(out: Path, until: str, *more: str) -> int:
    return main(["run", FIGURE2, "--virtual", "--until", until, "-o", str(out), "--plain", *more])


def test_run_refuses_an_existing_recording_and_keeps_it(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    assert _run_virtual(out, "3") == 0
    before = out.read_bytes()
    capsys.readouterr()
    assert _run_virtual(out, "6") == 2
    err = capsys.readouterr().err
    assert err.startswith(f"iotad: error: -o {out}: a recording is already there")
    assert "add --force to replace it" in err and f"{len(before):,} bytes" in err
    assert out.read_bytes() == before  # untouched
    assert max(m.log_time for m in read_recording(out).messages) <= 3e9


def test_run_with_force_replaces_it(tmp_path):
    out = tmp_path / "fig2.mcap"
    assert _run_virtual(out, "3") == 0
    assert _run_virtual(out, "6", "--force") == 0
    assert max(m.log_time for m in read_recording(out).messages) > 3e9  # the new, longer run


def test_the_first_member_of_a_split_recording_counts(tmp_path, capsys):
    (tmp_path / "long_0.mcap").write_bytes(b"part of an earlier run")
    assert _run_virtual(tmp_path / "long.mcap", "1") == 2
    assert f"({tmp_path / 'long_0.mcap'}," in capsys.readouterr().err
    assert not (tmp_path / "long.mcap").exists()


def test_record_refuses_before_it_connects(tmp_path, capsys):
    out = tmp_path / "r.mcap"
    out.write_bytes(b"an earlier recording")
    # a dead endpoint: the refusal comes first, at once
    assert main(["record", "iota/x/**", "-o", str(out), "--connect", "tcp/127.0.0.1:9"]) == 2
    assert "a recording is already there" in capsys.readouterr().err
    assert out.read_bytes() == b"an earlier recording"


def test_no_record_with_a_recording_named_is_refused_and_touches_nothing(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    out.write_bytes(b"kept")
    for how in (["--virtual", "--until", "1"], ["--until", "1"]):
        assert main(["run", FIGURE2, *how, "-o", str(out), "--no-record", "--plain"]) == 2
        assert "--no-record says there is none: give one of them" in capsys.readouterr().err
    assert out.read_bytes() == b"kept"


def test_default_names_never_collide(tmp_path):
    stamped = tmp_path / "figure2-20261123-191000.mcap"
    assert unused_recording_path(stamped) == stamped
    stamped.write_bytes(b"first")
    assert unused_recording_path(stamped) == tmp_path / "figure2-20261123-191000-2.mcap"
    (tmp_path / "figure2-20261123-191000-2_0.mcap").write_bytes(b"a split second")
    assert unused_recording_path(stamped) == tmp_path / "figure2-20261123-191000-3.mcap"


def test_a_real_time_run_refuses_before_any_node_starts(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    out.write_bytes(b"an earlier run")
    assert main(["run", FIGURE2, "--until", "1", "-o", str(out), "--plain"]) == 2
    captured = capsys.readouterr()
    assert "a recording is already there" in captured.err
    assert "started" not in captured.out  # no launcher line: nothing ran
    assert out.read_bytes() == b"an earlier run"


def test_a_name_is_claimed_before_anything_is_written(tmp_path, capsys):
    """Two runs started together both found no recording at the name, then both wrote it: a
    damaged file from two exit-0 runs. Now each claims the name (an empty file, created
    atomically) and the second is refused, in one line, before it starts."""
    from iotad.cli import CliError, claim_recording

    out = tmp_path / "fig2.mcap"
    assert claim_recording(str(out), force=False) and out.read_bytes() == b""
    try:
        claim_recording(str(out), force=False)
    except CliError as exc:
        assert "an empty file is there: another run has just claimed it" in str(exc)
    else:
        raise AssertionError("the second claim of one name was taken")
    assert _run_virtual(out, "1") == 2  # a run now: refused too
    assert "another run has just claimed it" in capsys.readouterr().err
    assert _run_virtual(out, "1", "--force") == 0 and read_recording(out).complete


def test_default_names_are_claimed_one_run_each(tmp_path):
    stamped = tmp_path / "recordings" / "figure2-20261123-191000.mcap"
    first = unused_recording_path(stamped, claim=True)
    second = unused_recording_path(stamped, claim=True)
    assert (first, second) == (stamped, tmp_path / "recordings" / "figure2-20261123-191000-2.mcap")
    assert first.exists() and second.exists()


def test_two_runs_started_together_on_one_name_leave_one_good_recording(tmp_path):
    out = tmp_path / "same.mcap"
    runs = [subprocess.Popen([sys.executable, "-m", "iotad", "run", FIGURE2, "--virtual", "--until", "20",
                              "-o", str(out), "--plain"], cwd=tmp_path, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(run.wait(timeout=120), run.stderr.read()) for run in runs]
    for run in runs:
        run.stdout.close()
        run.stderr.close()
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    refused = next(err for code, err in results if code == 2)
    assert "another run has just claimed it" in refused or "a recording is already there" in refused
    recording = read_recording(out)
    assert recording.complete and not recording.damaged


def test_a_run_that_stops_before_recording_leaves_no_empty_file(tmp_path, capsys):
    import socket

    out = tmp_path / "never.mcap"
    with socket.socket() as taken:  # the hub's port is in use: the launcher stops before the recorder
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["run", FIGURE2, "--until", "1", "-o", str(out), "--plain", "--port", str(port)]) == 2
    assert "is taken" in capsys.readouterr().err
    assert not out.exists()


def test_a_real_time_run_refuses_a_name_another_run_claimed(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    out.write_bytes(b"")  # what a run starting at the same moment has just created
    assert main(["run", FIGURE2, "--until", "1", "-o", str(out), "--plain"]) == 2
    captured = capsys.readouterr()
    assert "another run has just claimed it" in captured.err and "started" not in captured.out
