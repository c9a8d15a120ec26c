"""examples/mdl_arm.toml in virtual time, as `iotad run --virtual` runs it: requesters -> program
scheduler -> MDL interpreter (500 Hz) -> CAN motor node -> CAN bus -> simulated ODrives (PyBullet
arm). The recording holds every tick and every atom and program end, `iotad check` finds it
conformant, the preempted program resumes and the arm ends where the programs put it."""
from pathlib import Path

import pytest

pytest.importorskip("pybullet")

from iotad.cli import main  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SYSTEM = ROOT / "examples" / "mdl_arm.toml"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("mdl_arm") / "mdl_arm.mcap"
    assert main(["run", str(SYSTEM), "--virtual", "--until", "4", "-o", str(out)]) == 0
    return out


def test_the_recording_conforms(recording):
    assert main(["check", str(recording)]) == 0


def test_the_preempted_program_resumes_and_the_arm_reaches_its_goal(recording):
    trace = read_recording(recording).trace()
    ends = [(e["t"], e["value"]["program"], e["value"]["end"]) for e in trace
            if e["iota"] == "mdl" and e["action"] == "program_end"]
    # reach from 0.3 s, preempted by dodge at 1.3 s (1.0 s of its 2 s done); dodge's ramp ends on
    # its interrupt, its hold on T; reach, asked for again, resumes at 2.3 s with 1.0 s left
    assert [(p, end) for _, p, end in ends] == [("reach", "PREEMPTED"), ("dodge", "DONE"), ("reach", "DONE")]
    assert ends[0][0] == pytest.approx(1.3) and ends[2][0] == pytest.approx(3.798)
    atom_ends = [e["value"] for e in trace if e["iota"] == "mdl" and e["action"] == "atom_end"]
    dodge = atom_ends[0]
    assert (dodge["program"], dodge["end"], dodge["condition"]) == ("dodge", "INTERRUPTED", "position[4] < 1.0")
    assert 0.1 < dodge["elapsed"] < 0.6
    assert [(a["program"], a["atom"], a["end"], a["elapsed"]) for a in atom_ends[2:]] == \
        [("reach", 0, "DONE", pytest.approx(2.0)), ("reach", 1, "DONE", pytest.approx(0.5))]
    ticks = [e["t"] for e in trace if e["iota"] == "mdl" and e["action"] == "tick"]
    assert len(ticks) == 2000 and ticks[1] - ticks[0] == pytest.approx(0.002)
    states = [e["value"]["position"] for e in trace if e["iota"] == "motor" and e["action"] == "joint_states"]
    assert states[-1][:3] == pytest.approx([0.8, 0.3, -0.6], abs=0.01)
    assert not [e for e in trace if e["kind"] == "violation"]
