"""A station may queue the frames of one instant as one output (`can_tx_burst`, a list of
frames: one firing and one event instead of one per frame), which recording format 2's bus takes
on `tx_burst[k]` exactly as the same frames posted one by one: the other station receives the
same frames at the same times, the recording reads each frame as a `can_tx` of its own and
checks clean, and format 1, whose bus cannot take it, refuses the system in one line. This is
how the motor node's tick can burst (docs/design.md, "Recording format 2")."""
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.bursts import wire_frames
from iotad.recording.mcap_reader import read_recording
from system_iotas import pingpong_system


def run(tmp_path: Path, pinger: str, *options: str) -> Path:
    system = tmp_path / f"{pinger}.toml"
    system.write_text(pingpong_system(0.01, pinger=pinger))
    out = tmp_path / f"{pinger}.mcap"
    assert main(["run", str(system), "--virtual", "--until", "0.1", "-o", str(out), *options]) == 0
    return out


def heard(recording, node):
    return [(e["t"], e["value"]["id"], e["value"]["data"]) for e in recording.trace(node)
            if e["action"] == "can_rx" and e["kind"] == "input"]


def test_a_burst_of_frames_is_carried_as_the_same_frames_posted_one_by_one(tmp_path, capsys):
    one_by_one = read_recording(run(tmp_path, "CanRowPinger"))
    burst_path = run(tmp_path, "CanBurstPinger")
    bursts = read_recording(burst_path)
    assert heard(bursts, "echo") == heard(one_by_one, "echo") and len(heard(bursts, "echo")) >= 36
    assert heard(bursts, "pinger") == heard(one_by_one, "pinger")
    assert wire_frames(bursts, "can0") == wire_frames(one_by_one, "can0")
    own = [e for e in bursts.trace("pinger", derived=False) if e["kind"] == "output"]
    assert {e["action"] for e in own} == {"can_tx_burst"} and all(len(e["value"]) == 4 for e in own)
    # read back, each frame is a can_tx of its own, as sent one by one
    sent = [(e["t"], e["value"]["id"]) for e in bursts.trace("pinger") if e["action"] == "can_tx"]
    assert sent == [(e["t"], e["value"]["id"]) for e in one_by_one.trace("pinger") if e["action"] == "can_tx"]
    capsys.readouterr()
    assert main(["check", str(burst_path)]) == 0
    assert "every node conforms to its spec, every message was delivered as sent" in capsys.readouterr().out


def test_format_1_refuses_a_station_that_sends_bursts_in_one_line(tmp_path, capsys):
    system = tmp_path / "p.toml"
    system.write_text(pingpong_system(0.01, pinger="CanBurstPinger"))
    assert main(["run", str(system), "--virtual", "--until", "0.1", "-o", str(tmp_path / "p.mcap"),
                 "--format", "1"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    assert any("can_tx_burst" in line and "format 1" in line for line in err)
