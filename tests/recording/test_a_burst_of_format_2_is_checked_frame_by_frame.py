"""Recording format 2: a virtual run of arm_can records its bus's frames in bursts, and `iotad
check` still judges every frame: the honest recording passes, and a burst with one frame's data
altered, one frame dropped or duplicated, two frames swapped or one wire time shifted is caught. Replay of a
node reproduces it from the format 2 file, and the same run in format 1 carries the same frames
with the same ids, data and wire times (bench/burst_equivalence.py)."""
import copy
import importlib.util
import sys
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.bursts import is_burst, wire_frames
from iotad.recording.mcap_reader import read_recording
from recorded_systems import mutate

ROOT = Path(__file__).resolve().parents[2]
SYSTEM = ROOT / "examples" / "arm_can.toml"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "arm_can.mcap"
    assert main(["run", str(SYSTEM), "--virtual", "--until", "0.5", "-o", str(path)]) == 0
    return path


def _bursts_with(events, frames):
    return [k for k, e in enumerate(events) if is_burst(e) and len(e["value"]) >= frames]


def _check(path, capsys):
    code = main(["check", str(path)])
    return code, capsys.readouterr().out


def test_the_recording_is_format_2_with_bursts_and_checks_clean(recorded, capsys):
    recording = read_recording(recorded)
    assert recording.format_version == 2
    bursts = [e for e in recording.trace("arm_bus", derived=False) if is_burst(e)]
    assert len(bursts) > 10 and any(len(e["value"]) > 1 for e in bursts)
    # no per-frame events of the bus are in the file, only what the reader derives from bursts
    stored = recording.trace("arm_bus", derived=False)
    assert not [e for e in stored if e["action"] in ("rx", "frames")]
    frames = wire_frames(recording, "arm_bus")
    assert [f["end"] for f in frames] == sorted(f["end"] for f in frames)
    assert all(a["end"] <= b["start"] + 1e-12 for a, b in zip(frames, frames[1:]))  # one frame at a time
    code, out = _check(recorded, capsys)
    assert code == 0, out
    assert "every node conforms to its spec, every message was delivered as sent" in out


def _mutated(recorded, tmp_path, change):
    return mutate(recorded, tmp_path / "m.mcap", "arm_bus", change)


def test_one_frames_data_altered_in_a_burst_is_caught(recorded, tmp_path, capsys):
    def alter(events):
        k = _bursts_with(events, 2)[3]
        events[k] = copy.deepcopy(events[k])
        frame = events[k]["value"][1]
        frame["data"][0] ^= 0x01
        return events
    code, out = _check(_mutated(recorded, tmp_path, alter), capsys)
    assert code == 1
    assert "arm_bus" in out and ("wrong_value" in out or "altered" in out)


def test_one_frame_dropped_from_a_burst_is_caught(recorded, tmp_path, capsys):
    def drop(events):
        k = _bursts_with(events, 2)[3]
        events[k] = copy.deepcopy(events[k])
        del events[k]["value"][0]
        return events
    code, out = _check(_mutated(recorded, tmp_path, drop), capsys)
    assert code == 1 and "arm_bus" in out


def test_one_frame_duplicated_in_a_burst_is_caught(recorded, tmp_path, capsys):
    def duplicate(events):
        k = _bursts_with(events, 2)[3]
        events[k] = copy.deepcopy(events[k])
        value = events[k]["value"]
        value.insert(1, copy.deepcopy(value[0]))
        return events
    code, out = _check(_mutated(recorded, tmp_path, duplicate), capsys)
    assert code == 1 and "arm_bus" in out


def test_two_frames_swapped_in_a_burst_are_caught(recorded, tmp_path, capsys):
    def swap(events):
        k = next(k for k in _bursts_with(events, 2)
                 if events[k]["value"][0]["id"] != events[k]["value"][1]["id"])
        events[k] = copy.deepcopy(events[k])
        value = events[k]["value"]
        value[0], value[1] = value[1], value[0]
        return events
    code, out = _check(_mutated(recorded, tmp_path, swap), capsys)
    assert code == 1 and "arm_bus" in out


def test_one_wire_time_shifted_in_a_burst_is_caught(recorded, tmp_path, capsys):
    def shift(events):
        k = _bursts_with(events, 2)[3]
        events[k] = copy.deepcopy(events[k])
        events[k]["value"][1]["end"] += 20e-6
        return events
    code, out = _check(_mutated(recorded, tmp_path, shift), capsys)
    assert code == 1 and "arm_bus" in out


@pytest.mark.parametrize("node", ["motor", "odrives", "arm_bus"])
def test_a_node_replays_from_the_format_2_recording(recorded, node, capsys):
    assert main(["replay", str(recorded), "--node", node]) == 0
    assert "replay agrees" in capsys.readouterr().out


def test_format_1_and_format_2_runs_carry_the_same_frames():
    spec = importlib.util.spec_from_file_location("burst_equivalence", ROOT / "bench" / "burst_equivalence.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    same, lines = module.compare(SYSTEM, 0.5)
    assert same, "\n".join(lines)
    assert any("frames in format 1" in line and " 0 frames" not in line for line in lines)


def test_a_recovered_copy_of_a_format_2_file_holds_its_bursts_once(recorded, tmp_path, capsys):
    """`iotad recover` copies what the file holds (the bursts), not the frames the reader reads
    out of them: read back, the copy has each frame once and checks as the original does."""
    out = tmp_path / "copy.mcap"
    assert main(["recover", str(recorded), "-o", str(out)]) == 0
    original, copy_ = read_recording(recorded), read_recording(out)
    assert copy_.format_version == 2
    assert wire_frames(copy_, "arm_bus") == wire_frames(original, "arm_bus")
    assert sum(m.derived for m in copy_.messages) == sum(m.derived for m in original.messages) > 0
    assert len(copy_.messages) == len(original.messages)
    capsys.readouterr()
    assert main(["check", str(out)]) == 0


def test_info_says_format_2_and_how_many_messages_were_read_out_of_bursts(recorded, capsys):
    assert main(["info", str(recorded)]) == 0
    out = capsys.readouterr().out
    assert "format: 2" in out and "read out of bursts" in out
