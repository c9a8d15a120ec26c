"""Without auto_rearm an axis the node put in FAULT stays safe until the node's reset input
(`estop = false`) re-arms it. A drive armed behind the node's back while it is held (`iotad can
arm`, another master) is not adopted: the node stops it again, once per episode, and says so
(UNCOMMANDED_STATE): an ODrive in closed loop is sent Set_Axis_State IDLE, a CiA 402 drive in
OPERATION ENABLED a quick stop and a SYNC. No setpoint reaches it meanwhile; the reset arms it."""
import struct

from iotad.can import canopen as co
from iotad.can.frame import Frame
from motor_bench import CLOSED_LOOP, IDLE, SET_AXIS_STATE, SET_INPUT_POS, Bench, can, heartbeat, setpoints

ODRIVE = [{"name": "shoulder", "node_id": 1}]
CIA402 = [{"name": "wrist", "node_id": 3, "protocol": "cia402"}]


def idle_requests(bench, since):
    return [t for t, ident, rtr, data in bench.sent(since=since)
            if ident == 1 << 5 | SET_AXIS_STATE and struct.unpack("<I", data[:4])[0] == IDLE]


def test_an_odrive_armed_by_hand_while_held_in_fault_is_sent_idle_until_the_reset():
    bench = Bench(joints=ODRIVE)
    bench.arm_all(0.05)
    bench.hear(0.2, heartbeat(1, IDLE))  # it left closed loop on its own: FAULT (no auto_rearm)
    bench.run(0.25)
    assert bench.motor.axes[0].phase == "FAULT"
    bench.hear(0.3, heartbeat(1, CLOSED_LOOP))  # `iotad can arm --node 1`: closed loop again
    bench.hear(0.31, heartbeat(1, CLOSED_LOOP))  # still: once per episode
    for k in range(5):
        bench.post("setpoints", setpoints(1, [0.1]), t=0.32 + 0.01 * k)
    bench.run(0.4)
    assert len(idle_requests(bench, 0.3)) == 1
    assert [s["event"] for s in bench.status(0) if s["t"] >= 0.3] == ["UNCOMMANDED_STATE", "HEARTBEAT"]
    assert bench.motor.axes[0].phase == "FAULT"
    assert not [t for t, ident, _, _ in bench.sent(since=0.3) if ident == 1 << 5 | SET_INPUT_POS]
    bench.post("estop", False, t=0.5)  # the node's reset: it arms the axis itself
    bench.hear(0.6, heartbeat(1, CLOSED_LOOP))
    bench.run(0.65)
    assert [s["event"] for s in bench.status(0) if s["t"] >= 0.5][:3] == ["RESET", "ARM_SENT", "ARM_DONE"]
    assert bench.motor.axes[0].phase == "ARMED"


def tpdo1(statusword, position=0, torque=0):
    return Frame(0x183, struct.pack("<HiH", statusword, position, torque)).to_value()


def quick_stops(bench, since):
    return [t for t, ident, _, data in bench.sent(since=since) if ident == 0x203 and data[0] == co.CW_QUICK_STOP]


def test_a_cia402_drive_enabled_by_hand_while_held_in_fault_gets_a_quick_stop_until_the_reset():
    bench = Bench(joints=CIA402)
    bench.run(0.01)
    bench.motor.axes[0].phase = "ARMED"  # as if armed (the start-up is another test's)
    bench.hear(0.02, co.emcy(3, 0x2310, 0x03).to_value())  # its fault: FAULT, held (no auto_rearm)
    bench.run(0.03)
    assert bench.motor.axes[0].phase == "FAULT"
    enabled, quick_stop_active = 0x0027, 0x0007
    bench.hear(0.05, tpdo1(enabled))  # `iotad can arm --node 3`: fault reset and enabled again
    bench.hear(0.06, tpdo1(enabled))  # still: once per episode
    bench.run(0.07)
    assert len(quick_stops(bench, 0.05)) == 1
    assert [t for t, ident, _, _ in bench.sent(since=0.05) if ident == 0x080]  # the SYNC that takes it
    assert [s["event"] for s in bench.status(0) if s["t"] >= 0.05] == ["UNCOMMANDED_STATE"]
    bench.hear(0.08, tpdo1(quick_stop_active))
    bench.hear(0.09, tpdo1(enabled))  # enabled by hand again: a new episode
    bench.run(0.1)
    assert len(quick_stops(bench, 0.05)) == 2 and bench.motor.axes[0].phase == "FAULT"
    bench.post("estop", False, t=0.2)  # the node's reset: its own arming starts
    bench.run(0.25)
    assert [s["event"] for s in bench.status(0) if s["t"] >= 0.2][:2] == ["RESET", "ARM_SENT"]
