"""examples/arm_canopen.toml in one process in virtual time, the motor node cut off the bus
mid-motion: every CiA 402 drive, whose heartbeat consumer watches the motor node's heartbeat,
sends EMCY 0x8130 (heartbeat error) and reports FAULT REACTION ACTIVE, then FAULT, within the
configured consumer time (lost_after x master_heartbeat) of the master's last heartbeat on the
bus, to one control step (the drive's clock), measured on the recorded frames; the motors then stop."""
import pytest

pytest.importorskip("pybullet")

from arm_hil import ROOT  # noqa: E402
from arm_trajectory import ArmTrajectory  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can.frame import Frame  # noqa: E402
from iotad.can.virtual_bus import CanBus  # noqa: E402
from iotad.kernel.compose import Composite  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402
from nodes.can_motor import CanMotor  # noqa: E402
from sim.cia402_sim import SimulatedCia402Drives  # noqa: E402
from test_watchdog_after_the_motor_node_falls_silent_in_virtual_time import Cut  # noqa: E402

EXAMPLE = ROOT / "examples" / "arm_canopen.toml"
CUT = 1.2  # s: mid first leg


def params(name):
    return next(node.params for node in load_system(EXAMPLE).nodes.values() if node.name == name)


@pytest.fixture(scope="module")
def run():
    motor = params("motor")
    drives = params("drives")
    system = Composite(
        "arm", ArmTrajectory("trajectory", **params("trajectory")), CanMotor("motor", **motor),
        Cut("cable", at=CUT), CanBus("bus", stations=2), SimulatedCia402Drives("drives", **drives),
        bind=[("trajectory.setpoints", "motor.setpoints"), ("motor.joint_states", "trajectory.joint_states"),
              ("motor.can_tx", "cable.inp"), ("cable.out", "bus.tx[0]"), ("bus.rx[0]", "motor.can_rx"),
              ("drives.can_tx", "bus.tx[1]"), ("bus.rx[1]", "drives.can_rx")])
    engine = Engine(system)
    sim = engine.iota("arm/drives")
    try:
        engine.run(until=2.0)
        ends = {drive.node_id: (drive.state, drive.transitions[-3:], drive.velocity) for drive in sim.drives}
    finally:
        sim.close()
    motor_node = engine.iota("arm/motor")
    consumer = motor_node.lost_after * motor_node.master_heartbeat
    return [dict(e, node=e["iota"].split("/")[-1]) for e in engine.trace], consumer, drives["step_period"], ends


def test_each_drive_faults_within_the_consumer_time_of_the_masters_last_heartbeat(run):
    trace, consumer, step, _ = run
    rx = [(e["t"], co.decode(Frame.from_value(e["value"]))) for e in trace
          if e["node"] == "drives" and e["action"] == "can_rx" and e["kind"] == "input"]
    tx = [(e["t"], co.decode(Frame.from_value(e["value"]))) for e in trace
          if e["node"] == "drives" and e["action"] == "can_tx" and e["kind"] == "output"]
    last_beat = max(t for t, m in rx if m.kind == "HEARTBEAT" and m.node_id == 127)
    assert CUT - 0.051 < last_beat <= CUT + 0.002  # sent by the cut, received behind a few queued frames
    tracker = co.PdoTracker(range(1, 7))
    for node in range(1, 7):
        emcy = [(t, m) for t, m in tx if m.kind == "EMCY" and m.node_id == node]
        assert len(emcy) == 1 and emcy[0][1].fields["code"] == 0x8130
        # the drive keeps time in control steps (a heartbeat heard between two steps counts from the
        # step before): the fault comes at the first step past the consumer time, within one step of it
        assert consumer - step < emcy[0][0] - last_beat <= consumer + step
        states = [(t, co.state_of(tracker_values(tracker, m)[0x6041])) for t, m in tx
                  if m.kind == "TPDO1" and m.node_id == node and t > CUT - 0.1]
        before = [s for t, s in states if t < emcy[0][0]]
        assert before and set(before) == {"OPERATION ENABLED"}
        # no SYNC comes any more, so no TPDO tells; the drive itself says FAULT (after the brake ramp)


def tracker_values(tracker, message):
    od = tracker.od(message.node_id)
    return co.unpack_pdo(od, tracker.maps[message.frame.id], message.frame.data)


def test_the_drives_end_in_fault_with_their_motors_stopped(run):
    trace, _, _, ends = run
    for node, (state, transitions, velocity) in ends.items():
        assert state == "FAULT" and transitions[-2:] == [13, 14], node
        assert abs(velocity) < 0.05, node  # turns/s: braked, then the power stage off
    # the motor node heard it: its last joint status of each joint says so by its 402 state
    last = {}
    for e in trace:
        if e["node"] == "motor" and e["action"] == "joint_status":
            last[e["value"]["joint"]] = e["value"]
    assert {v["axis_state"] for v in last.values()} <= {co.STATE_NUMBER["FAULT REACTION ACTIVE"], co.STATE_NUMBER["FAULT"],
                                                          co.STATE_NUMBER["OPERATION ENABLED"]}
