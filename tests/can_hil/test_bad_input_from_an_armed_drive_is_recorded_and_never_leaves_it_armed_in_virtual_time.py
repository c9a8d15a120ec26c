"""Bad input from an armed drive, the arm of examples/arm_canopen.toml in virtual time, the frames of
drive 1 (joint1) mangled on their way to the motor node from 1.2 s on:

- TPDO1 one byte short: each is a bad_frame WRONG_DLC, and with no valid statusword the TPDO
  timeout (3 SYNCs) takes the axis out of ARMED (TPDO_TIMEOUT, lost);
- its heartbeat of an NMT state no standard has (99): each is a bad_frame BAD_VALUE, not believed,
  so the heartbeat's own timeout (lost_after periods) takes the axis out of ARMED (LOST);
- an EMCY of 3 bytes is a bad_frame WRONG_DLC; a well-formed EMCY with a code is a fault at once.

In every case no engine violation (the node never crashes), the other joints stay armed, and
joint1 gets no setpoint (RPDO with ENABLE OPERATION) after it was reported not armed.
"""
import pytest

pytest.importorskip("pybullet")

from arm_hil import ROOT  # noqa: E402
from arm_trajectory import ArmTrajectory  # noqa: E402
from iotad import Input, Internal, Iota, Output, Param  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can.frame import CAN_FRAME, Frame  # noqa: E402
from iotad.can.virtual_bus import CanBus  # noqa: E402
from iotad.kernel.compose import Composite  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402
from nodes.can_motor import CanMotor  # noqa: E402
from sim.cia402_sim import SimulatedCia402Drives  # noqa: E402

EXAMPLE = ROOT / "examples" / "arm_canopen.toml"
FROM = 1.2


def short_tpdo(frame):
    return Frame(frame.id, frame.data[:-1]) if frame.id == 0x181 else frame


def unknown_heartbeat(frame):
    return Frame(frame.id, bytes((99,))) if frame.id == 0x701 else frame


def emcy_3_bytes(frame):
    return Frame(frame.id, frame.data[:3]) if frame.id == 0x081 else frame


class Mangle(Iota):
    """Frames from the bus to the motor node, changed by `change` from `at` on (time of arrival)."""

    at = Param(1.0)
    change = Param(None)
    inp = Input(CAN_FRAME, switching=0)
    out = Output(CAN_FRAME, switching=0)
    start = Internal()

    def init(self):
        self.queue, self.mangling = [], False

    @inp.input
    def got(self, value):
        frame = Frame.from_value(value)
        self.queue.append((self.change(frame) if self.mangling else frame).to_value())

    @start.action(after="at")
    def started(self):
        self.mangling = True

    @out.action(value=lambda self: self.queue[0], when=lambda self: bool(self.queue))
    def passed(self):
        self.queue.pop(0)


def params(name):
    return dict(next(node.params for node in load_system(EXAMPLE).nodes.values() if node.name == name))


def run(change, until=2.0, fault=None):
    system = Composite(
        "arm", ArmTrajectory("trajectory", **params("trajectory")), CanMotor("motor", **params("motor")),
        Mangle("mangle", at=FROM, change=change), CanBus("bus", stations=2),
        SimulatedCia402Drives("drives", **params("drives")),
        bind=[("trajectory.setpoints", "motor.setpoints"), ("motor.joint_states", "trajectory.joint_states"),
              ("motor.can_tx", "bus.tx[0]"), ("bus.rx[0]", "mangle.inp"), ("mangle.out", "motor.can_rx"),
              ("drives.can_tx", "bus.tx[1]"), ("bus.rx[1]", "drives.can_rx")])
    engine = Engine(system)
    sim = engine.iota("arm/drives")
    try:
        if fault:
            engine.run(until=FROM)
            sim.drive("joint1").fault(fault)  # the drive's own fault: its EMCY goes out
        engine.run(until=until)
    finally:
        sim.close()
    return engine, [dict(e, node=e["iota"].split("/")[-1]) for e in engine.trace]


def joint1_after(trace):
    """(bad frame reasons, joint1's status events after FROM, the time it was first not ARMED,
    the times of ENABLE OPERATION RPDOs the node sent drive 1 after that report)."""
    bad = [e["value"]["reason"] for e in trace if e["node"] == "motor" and e["action"] == "bad_frame" and e["t"] >= FROM]
    status = [(e["t"], e["value"]) for e in trace if e["node"] == "motor" and e["action"] == "joint_status"
              and e["value"]["joint"] == 0 and e["t"] >= FROM]
    safe = next(t for t, v in status if v["phase"] != "ARMED")
    safe_at = next(k for k, e in enumerate(trace) if e["node"] == "motor" and e["action"] == "joint_status"
                   and e["value"]["joint"] == 0 and e["t"] >= FROM and e["value"]["phase"] != "ARMED")
    tracker = co.PdoTracker(range(1, 7))
    rpdos = []
    for k, e in enumerate(trace):
        if e["node"] == "motor" and e["action"] == "can_tx" and e["kind"] == "output":
            frame = Frame.from_value(e["value"])
            message = co.decode(frame)
            tracker.feed(message)
            if frame.id == 0x201 and k > safe_at:
                word = co.unpack_pdo(tracker.od(1), tracker.maps[0x201], frame.data)[0x6040]
                if co.command_of(word) == "ENABLE OPERATION":
                    rpdos.append(e["t"])
    return bad, [v["event"] for t, v in status], safe, rpdos


def others_stay_armed(trace):
    last = {}
    for e in trace:
        if e["node"] == "motor" and e["action"] == "joint_status":
            last[e["value"]["joint"]] = e["value"]["phase"]
    return all(last[j] == "ARMED" for j in range(1, 6))


@pytest.mark.parametrize("change, reason, event, within", [
    (short_tpdo, "WRONG_DLC", "TPDO_TIMEOUT", 4 * 0.02),
    (unknown_heartbeat, "BAD_VALUE", "LOST", 0.1 * 3 + 0.1),
], ids=["tpdo-of-the-wrong-length", "heartbeat-of-an-unknown-state"])
def test_a_mangled_frame_is_recorded_and_the_axis_leaves_armed(change, reason, event, within):
    engine, trace = run(change)
    bad, events, safe, rpdos = joint1_after(trace)
    assert bad and set(bad) == {reason}
    assert event in events and safe - FROM <= within
    assert not [e for e in trace if e["kind"] == "violation"]
    # auto_rearm (the example's) tries again; the bad frames go on, so it never reaches ARM_DONE
    assert "ARM_DONE" not in events
    assert rpdos == []
    assert others_stay_armed(trace)


def test_a_short_emcy_is_recorded_and_a_good_one_is_a_fault_at_once():
    _, trace = run(emcy_3_bytes, until=1.3, fault=0x2310)
    bad, events, safe, rpdos = joint1_after(trace)
    assert bad == ["WRONG_DLC"]  # the drive's EMCY 0x2310, cut to 3 bytes
    # its statusword (FAULT REACTION ACTIVE) still says it is not enabled
    assert "DISARMED" in events and rpdos == []
    _, trace = run(lambda frame: frame, until=1.3, fault=0x2310)
    _, events, safe, rpdos = joint1_after(trace)
    first = [e["value"] for e in trace if e["node"] == "motor" and e["action"] == "joint_status"
             and e["value"]["joint"] == 0 and e["t"] == safe][0]
    assert (first["event"], first["phase"], first["axis_error"]) == ("EMCY", "UNARMED", 0x2310)
    assert safe - FROM < 0.005 and rpdos == []
