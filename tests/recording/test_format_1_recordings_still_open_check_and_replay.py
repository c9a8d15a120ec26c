"""Recordings of format 1 (a modelled bus firing an `rx` per frame and receiver and a `frames` log
per frame; "iotad-mcap/1"), committed as they were written before format 2, still open, check
and replay with the readers of format 2: `iotad info` says format 1, `iotad check` passes, each
CAN node replays, and candump lists the bus's frames."""
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.bursts import wire_frames
from iotad.recording.mcap_reader import read_recording

DATA = Path(__file__).parent / "data"
FIXTURES = {"format1_arm_can.mcap": ("arm_bus", ["arm_bus", "odrives"]),
            "format1_buggy.mcap": ("can0", ["can0", "body"])}


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_a_format_1_file_reads_as_format_1_with_its_frames(name):
    recording = read_recording(DATA / name)
    assert recording.info.get("format") in (None, "iotad-mcap/1") and recording.format_version == 1
    assert not any(m.derived for m in recording.messages)  # nothing to expand: it has no bursts
    bus, _ = FIXTURES[name]
    frames = wire_frames(recording, bus)
    assert frames and all(f["end"] > f["start"] for f in frames)


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_a_format_1_file_passes_info_and_check(name, capsys):
    assert main(["info", str(DATA / name)]) == 0
    assert "format: 1" in capsys.readouterr().out
    assert main(["check", str(DATA / name)]) == 0
    assert "every node conforms to its spec, every message was delivered as sent" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_the_nodes_of_a_format_1_file_replay(name, capsys):
    _, nodes = FIXTURES[name]
    for node in nodes:
        assert main(["replay", str(DATA / name), "--node", node]) == 0, node
        assert "replay agrees" in capsys.readouterr().out


def test_candump_of_a_format_1_file_lists_its_frames(capsys):
    assert main(["candump", str(DATA / "format1_arm_can.mcap")]) == 0
    out = capsys.readouterr().out
    assert "Set_Input_Pos" in out or "0x0" in out
