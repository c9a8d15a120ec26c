"""The arm of examples/arm_canopen.toml in virtual time, its units taken from the drives:

- the motor node reads each drive's rated torque (0x6076) and encoder resolution (0x608F), and the
  gear ratio and feed constant (0x6091, 0x6092) where the drive has them, at start-up;
- drives rated 0.15 N.m (an EDS that says so; iotad's own EDS says 1 N.m): every effort the node
  reports equals the torque actual the drive last sent (per mille of ITS rated torque), measured
  on the recorded frames;
- a joint table whose explicit counts_per_turn or rated_torque contradicts the drive's is refused
  with one line that names both values, SCALE_MISMATCH in joint_status, and that axis is never
  armed (the others are).
"""
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

EXAMPLE = ROOT / "examples" / "arm_canopen.toml"


def params(name):
    return dict(next(node.params for node in load_system(EXAMPLE).nodes.values() if node.name == name))


def run(until, *, eds=None, joints=None):
    motor = params("motor")
    if joints:
        motor["joints"] = [dict(joint, **joints.get(joint["name"], {})) for joint in motor["joints"]]
    drives = params("drives") | ({"eds": str(eds)} if eds else {})
    system = Composite(
        "arm", ArmTrajectory("trajectory", **params("trajectory")), CanMotor("motor", **motor),
        CanBus("bus", stations=2), SimulatedCia402Drives("drives", **drives),
        bind=[("trajectory.setpoints", "motor.setpoints"), ("motor.joint_states", "trajectory.joint_states"),
              ("motor.can_tx", "bus.tx[0]"), ("bus.rx[0]", "motor.can_rx"),
              ("drives.can_tx", "bus.tx[1]"), ("bus.rx[1]", "drives.can_rx")])
    engine = Engine(system)
    sim = engine.iota("arm/drives")
    try:
        engine.run(until=until)
    finally:
        sim.close()
    return [dict(e, node=e["iota"].split("/")[-1]) for e in engine.trace]


def test_every_effort_reported_is_the_torque_actual_the_drive_sent(tmp_path):
    text = co.DRIVE_EDS.read_text()
    head, _, rest = text.partition("[6076]")
    rated, _, tail = rest.partition("\n\n")
    eds = tmp_path / "drive_0_15nm.eds"
    eds.write_text(head + "[6076]" + rated.replace("DefaultValue=1000", "DefaultValue=150") + "\n\n" + tail)
    trace = run(1.5, eds=eds)
    reads = [co.decode(Frame.from_value(e["value"])).fields for e in trace
             if e["node"] == "motor" and e["action"] == "can_tx" and Frame.from_value(e["value"]).id & 0x780 == co.RSDO]
    assert {(f["index"], f["subindex"]) for f in reads if f["service"] == "upload"} >= {
        (0x6076, 0), (0x608F, 1), (0x608F, 2), (0x6091, 1), (0x6092, 1)}
    tracker = co.PdoTracker(range(1, 7))
    torque = {}
    compared = 0
    for e in trace:
        if e["node"] == "motor" and e["action"] == "can_rx" and e["kind"] == "input":
            frame = Frame.from_value(e["value"])
            message = co.decode(frame)
            if message.kind == "TPDO1":
                values = co.unpack_pdo(tracker.od(message.node_id), tracker.maps[frame.id], frame.data)
                torque[message.node_id] = values[0x6077] / 1000.0 * 0.150  # N.m: per mille of the drive's 0.15
        elif e["node"] == "motor" and e["action"] == "joint_states" and len(torque) == 6:
            assert e["value"]["effort"] == pytest.approx([torque[n] for n in range(1, 7)], abs=1e-12)
            compared += 1
    assert compared > 20 and any(abs(t) > 0.01 for t in torque.values())


def test_a_table_scale_that_contradicts_the_drive_is_refused_with_one_line(capfd):
    trace = run(1.0, joints={"joint1": {"counts_per_turn": 4096}, "joint2": {"rated_torque": 2.0},
                             "joint3": {"counts_per_turn": 65536, "rated_torque": 1.0}})
    status = [e["value"] for e in trace if e["node"] == "motor" and e["action"] == "joint_status"]
    mismatch = {s["joint"]: s for s in status if s["event"] == "SCALE_MISMATCH"}
    assert sorted(mismatch) == [0, 1]
    assert (mismatch[0]["disarm_reason"], mismatch[0]["requested"], mismatch[0]["applied"]) == (0x608F, 4096, 65536)
    assert (mismatch[1]["disarm_reason"], mismatch[1]["requested"], mismatch[1]["applied"]) == (0x6076, 2.0, 1.0)
    armed = {s["joint"] for s in status if s["event"] == "ARM_DONE"}
    assert armed == {2, 3, 4, 5}  # joint3 states the drive's own values: no contradiction
    assert all(s["phase"] == "FAULT" for s in status if s["joint"] in (0, 1) and s["event"] != "ARM_SENT"
               and status.index(s) > status.index(mismatch[s["joint"]]))
    lines = [line for line in capfd.readouterr().err.splitlines() if "contradicts" in line]
    assert lines == [
        "CanMotor: joint joint1: the joint table's counts_per_turn = 4096 contradicts the drive's increments per "
        "motor turn (0x608F) = 65536; not armed (fix the table or the drive)",
        "CanMotor: joint joint2: the joint table's rated_torque = 2 contradicts the drive's rated torque (0x6076, "
        "N.m) = 1; not armed (fix the table or the drive)"]
