"""In recording format 2 the motor node sends the frames of one instant (a tick's requests, a
setpoints message's commands) as one `can_tx_burst` output, and the simulated drives their answers
of one instant (a CiA 402 drive set's TPDOs at a SYNC) likewise: one firing and one event instead of
one per frame. The wire does not change: the same system run in format 1 (one `can_tx` per frame)
carries the same frames, ids, data and wire times, every station hears the same frames at the same
times, the format 2 recording checks clean, and replay of the motor node and of the drives from it
agrees."""
import shutil
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.bursts import wire_frames
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]


def run(tmp_path: Path, example: str, recording_format: int) -> Path:
    out = tmp_path / f"{example}-{recording_format}.mcap"
    assert main(["run", str(ROOT / "examples" / f"{example}.toml"), "--virtual", "--until", "1", "-o", str(out),
                 "--format", str(recording_format)]) == 0
    return out


def on_grid(recording) -> list:
    """The bus's frames with their wire times in whole ns (format 1 logs a frame's end and duration)."""
    return [dict(f, start=round(f["start"] * 1e9), end=round(f["end"] * 1e9)) for f in wire_frames(recording, "arm_bus")]


def heard(recording, node: str, action: str, kind: str) -> list:
    return [(e["t"], e["value"]["id"], e["value"]["rtr"], e["value"]["data"]) for e in recording.trace(node)
            if e["action"] == action and e["kind"] == kind]


@pytest.mark.parametrize("example, drives", [("arm_can", "odrives"), ("arm_canopen", "drives")])
def test_bursts_carry_the_frames_that_one_by_one_carried(tmp_path, capsys, example, drives):
    one = read_recording(run(tmp_path, example, 1))
    path = run(tmp_path, example, 2)
    two = read_recording(path)
    assert (one.format_version, two.format_version) == (1, 2)
    assert on_grid(two) == on_grid(one) and len(on_grid(two)) > 500
    for node in ("motor", drives):
        assert heard(two, node, "can_tx", "output") == heard(one, node, "can_tx", "output")  # read back per frame
        assert heard(two, node, "can_rx", "input") == heard(one, node, "can_rx", "input")

    motor = [e for e in two.trace("motor", derived=False) if e["kind"] == "output"]
    assert not [e for e in motor if e["action"] == "can_tx"]
    bursts = [e for e in motor if e["action"] == "can_tx_burst"]
    assert max(len(e["value"]) for e in bursts) >= 6  # a tick's requests to six axes, in one output
    assert sum(len(e["value"]) for e in bursts) == len(heard(two, "motor", "can_tx", "output"))
    answers = [e for e in two.trace(drives, derived=False) if e["action"] == "can_tx_burst"]
    assert answers
    if example == "arm_canopen":  # six drives' TPDOs at each SYNC, in one output
        assert max(len(e["value"]) for e in answers) >= 6
    # the same instants, in fewer firings (a frame caused after the instant's burst went, by a
    # frame heard at that instant, goes in a second burst then)
    one_by_one = [e for e in one.trace("motor", derived=False) if e["action"] == "can_tx"]
    assert {e["t"] for e in bursts} == {e["t"] for e in one_by_one}
    assert len(bursts) < 0.8 * len(one_by_one)

    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    assert "every node conforms to its spec, every message was delivered as sent" in capsys.readouterr().out
    for node in ("motor", drives):
        assert main(["replay", str(path), "--node", node]) == 0
        assert f"{node}: replay agrees" in capsys.readouterr().out


def test_a_file_that_says_how_a_station_sends_is_obeyed(tmp_path):
    # tx_bursts = false in the system file: frame by frame, on format 2's bus too
    text = (ROOT / "examples" / "arm_can.toml").read_text()
    head, tail = text.split('python = "nodes.can_motor:CanMotor"\n', 1)
    params = tail.index("[node.params]\n") + len("[node.params]\n")
    system = tmp_path / "arm_can.toml"
    shutil.copy(ROOT / "examples" / "arm_trajectory.py", tmp_path)  # the python file it names, beside it
    system.write_text(head + 'python = "nodes.can_motor:CanMotor"\n' + tail[:params] + "tx_bursts = false\n"
                      + tail[params:])
    out = tmp_path / "plain.mcap"
    assert main(["run", str(system), "--virtual", "--until", "0.3", "-o", str(out)]) == 0
    actions = {e["action"] for e in read_recording(out).trace("motor", derived=False) if e["kind"] == "output"}
    assert "can_tx" in actions and "can_tx_burst" not in actions
