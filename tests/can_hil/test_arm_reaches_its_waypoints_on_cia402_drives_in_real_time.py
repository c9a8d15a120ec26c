"""examples/arm_canopen.toml as processes in real time on a CAN bus (conftest's `system_can_tier`:
the kernel's vcan, else udp_multicast in a private network namespace, else user-mode Linux): the
motor node starts the simulated CiA 402 drives over NMT and SDO, enables them and drives them by
RPDO at SYNC, and the arm ends within 0.01 rad of the last waypoint, as in virtual time. It runs
12 s after every node is live: on a loaded two-core machine the simulated drives' process runs its
physics several times slower than the wall clock (it runs late rather than skip), and the
trajectory's 3.5 s take longer to play out. The bus logger names every frame it heard as CANopen."""
import sys

import pytest

pytest.importorskip("pybullet")

from arm_hil import FINAL, ROOT, settled_positions  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can.frame import Frame  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402


@pytest.fixture(scope="module")
def trace(system_can_tier, tmp_path_factory):
    folder = tmp_path_factory.mktemp("arm_canopen_rt")
    text = (ROOT / "examples" / "arm_canopen.toml").read_text()
    text = text.replace('python = "arm_trajectory.py:', f'python = "{ROOT / "examples" / "arm_trajectory.py"}:')
    text = text.replace('interface = "socketcan"\nchannel = "vcan0"', 'interface = "env"')
    system = folder / "arm_canopen.toml"
    system.write_text(text)
    recording = folder / "arm.mcap"
    result = system_can_tier.run([sys.executable, "-m", "iotad", "run", str(system), "--until", "12", "--after-live",
                                  "--plain", "--port", "0", "-o", str(recording), "--log-dir", str(folder / "logs")],
                                 timeout=300, cwd=str(folder)).check()
    print(f"\nCAN tier {system_can_tier.describe()}: run took {result.seconds:.1f} s")
    return read_recording(recording).trace()


def test_the_arm_ends_within_0_01_rad_of_the_last_waypoint_in_real_time(trace):
    settled = settled_positions(trace, since=0.0)
    assert settled is not None, "no moment with every joint armed for 2 s"
    t, positions = settled
    assert positions == pytest.approx(FINAL, abs=0.01), f"at t={t:.2f}"


def test_the_drives_were_driven_over_canopen(trace):
    got = [co.decode(Frame.from_value(e["value"])).kind for e in trace
           if e.get("node") == "drives" and e.get("action") == "can_rx" and e.get("kind") == "input"]
    assert got.count("SYNC") > 100 and got.count("RPDO1") > 600 and "SDO_REQUEST" in got and "NMT" in got


def test_the_bus_logger_names_the_frames_as_canopen(trace):
    # the real-time bus logger of a bus with CiA 402 stations (CanopenBusLogger): every frame it
    # heard by its CANopen service, none as an ODrive message
    from iotad.can.canopen_frame_log import CANOPEN_MESSAGES

    log = [e["value"] for e in trace if e.get("node") == "arm_bus" and e.get("action") == "frames"
           and e.get("kind") == "output"]
    assert log and not [r for r in log if r["message"] not in CANOPEN_MESSAGES]
    messages = [r["message"] for r in log]
    assert messages.count("SYNC") > 100 and messages.count("RPDO1") > 600 and messages.count("TPDO1") > 600
    assert {"NMT", "HEARTBEAT", "SDO_REQUEST", "SDO_RESPONSE"} <= set(messages)
