"""examples/arm_can.toml in one process in virtual time (`iotad run --virtual`): the trajectory
requester's setpoints go through the CAN motor node, the modelled 1 Mbit/s bus and the simulated
ODrives to the PyBullet arm, which ends within 0.01 rad of the last waypoint; the recording
checks, and `iotad candump` prints its frames by name."""
import pytest

pytest.importorskip("pybullet")

from arm_hil import EXAMPLE, FINAL, final_positions, frames  # noqa: E402
from iotad.cli import main  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("arm") / "arm.mcap"
    assert main(["run", str(EXAMPLE), "--virtual", "--until", "5", "-o", str(path)]) == 0
    return path


def test_the_arm_ends_within_0_01_rad_of_the_last_waypoint(recording):
    trace = read_recording(recording).trace()
    assert final_positions(trace) == pytest.approx(FINAL, abs=0.01)
    # it went through CAN: every setpoint became Set_Input_Pos frames the simulated axes received
    received = [m.name for _, _, m in frames(trace, "odrives", "can_rx") if m is not None]
    assert received.count("Set_Input_Pos") > 6 * 200
    assert {"Clear_Errors", "Set_Controller_Mode", "Set_Limits", "Set_Axis_State"} <= set(received)
    # and the middle waypoint was passed on the way
    passed = [e["value"]["position"] for e in trace if e.get("node") == "motor" and e.get("action") == "joint_states"]
    assert min(abs(p[0] - 0.5) for p in passed) < 0.02


def test_the_recording_of_the_virtual_run_checks(recording, capsys):
    assert main(["check", str(recording)]) == 0
    assert "every node conforms to its spec" in capsys.readouterr().out
