"""A recording is the evidence of a run: `iotad run -o` and `iotad record -o` refuse to write over
one (or over a split recording's first member) in one line, before anything starts, and replace it
only with --force. Default names (time-stamped) never collide: a second run in the same second
gets `-2`."""
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_io import read_recording, unused_recording_path

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


def test_no_record_needs_no_force(tmp_path):
    out = tmp_path / "fig2.mcap"
    out.write_bytes(b"kept")
    assert main(["run", FIGURE2, "--virtual", "--until", "1", "-o", str(out), "--no-record", "--plain"]) == 0
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
