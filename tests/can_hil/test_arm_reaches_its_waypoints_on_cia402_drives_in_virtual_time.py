"""examples/arm_canopen.toml in one process in virtual time: the arm of arm_can.toml on simulated
CiA 402 drives (CANopen: NMT, SDO start-up, RPDO setpoints at SYNC, TPDO state) ends within 0.01 rad
of the same last waypoint, and its recording checks. A mixed bus, three ODrives and three CiA 402
drives on other node ids behind the same motor node, does the same."""
import pytest

pytest.importorskip("pybullet")

from arm_hil import FINAL, ROOT, final_positions, mixed_canopen_system  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can.frame import Frame  # noqa: E402
from iotad.cli import main  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402

EXAMPLE = ROOT / "examples" / "arm_canopen.toml"


def run(path, system):
    assert main(["run", str(system), "--virtual", "--until", "5", "-o", str(path)]) == 0
    return read_recording(path)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    return run(tmp_path_factory.mktemp("arm") / "arm.mcap", EXAMPLE)


def received(trace, node):
    return [Frame.from_value(e["value"]) for e in trace
            if e.get("node") == node and e.get("action") == "can_rx" and e.get("kind") == "input"]


def test_the_arm_ends_within_0_01_rad_of_the_last_waypoint_on_cia402_drives(recording):
    trace = recording.trace()
    assert final_positions(trace) == pytest.approx(FINAL, abs=0.01)
    kinds = [co.decode(frame) for frame in received(trace, "drives")]
    assert sum(m.kind == "SYNC" for m in kinds) > 200          # a SYNC every 20 ms
    rpdos = [m for m in kinds if m.kind == "RPDO1"]
    assert len(rpdos) > 6 * 200                                # a setpoint per joint per 20 ms
    nmt = [m.fields["command"] for m in kinds if m.kind == "NMT"]
    assert nmt.count("START") >= 6 and nmt.count("ENTER_PRE_OPERATIONAL") >= 6
    writes = {(m.fields["index"], m.fields["subindex"]) for m in kinds if m.kind == "SDO_REQUEST"}
    assert {(0x1016, 1), (0x1017, 0), (0x6060, 0), (0x1600, 1), (0x1A00, 1)} <= writes
    events = [e["value"]["event"] for e in trace if e.get("action") == "joint_status"]
    assert events.count("ARM_DONE") == 6 and "DISARMED" not in events


def test_every_frame_of_the_run_decodes_against_the_eds(recording):
    tracker = co.PdoTracker(range(1, 7))
    lines = [tracker.describe(frame) for frame in received(recording.trace(), "drives")
             + received(recording.trace(), "motor")]
    assert not [line for line in lines if "malformed" in line]
    assert any("Statusword=" in line and "OPERATION ENABLED" in line for line in lines)


def test_the_recording_of_the_cia402_arm_checks(tmp_path, capsys):
    path = tmp_path / "arm.mcap"
    run(path, EXAMPLE)
    assert main(["check", str(path)]) == 0
    assert "every node conforms to its spec" in capsys.readouterr().out


def test_a_mixed_bus_of_odrives_and_cia402_drives_reaches_the_waypoint(tmp_path):
    system = mixed_canopen_system(tmp_path)
    trace = run(tmp_path / "mixed.mcap", system).trace()
    assert final_positions(trace) == pytest.approx(FINAL, abs=0.01)
    frames = received(trace, "drives")
    odrive_ids = {f.id >> 5 for f in frames if 0 < f.id < 0x80}  # 0: NMT
    canopen_ids = {f.id & 0x7F for f in frames if f.id & 0x780 == co.RPDO[0]}
    assert odrive_ids == {1, 2, 3} and canopen_ids == {4, 5, 6}


def test_profile_position_drives_reach_the_waypoint_too(tmp_path):
    text = EXAMPLE.read_text().replace('python = "arm_trajectory.py:', f'python = "{ROOT / "examples" / "arm_trajectory.py"}:')
    text = text.replace('protocol = "cia402"\n', 'protocol = "cia402"\noperation_mode = "pp"\nacceleration_limit = 20.0\n')
    system = tmp_path / "pp.toml"
    system.write_text(text)
    trace = run(tmp_path / "pp.mcap", system).trace()
    assert final_positions(trace) == pytest.approx(FINAL, abs=0.01)
    writes = [co.decode(frame) for frame in received(trace, "drives")]
    modes = {m.fields["data"][0] for m in writes if m.kind == "SDO_REQUEST" and m.fields["index"] == 0x6060}
    assert modes == {co.MODES["PP"]}
    # each setpoint raised the new set-point bit, then lowered it
    words = [int.from_bytes(m.fields["data"][:2], "little") for m in writes if m.kind == "RPDO1"]
    assert 0x3F in words and 0x2F in words
