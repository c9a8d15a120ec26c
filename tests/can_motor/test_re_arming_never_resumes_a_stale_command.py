"""The firmware keeps an axis's input velocity and torque across IDLE (only a position input is
reset, to where the axis is), so an axis re-armed after a watchdog trip, an estop reset or a
restart of the node would resume the speed it was last given (tests/sim shows it). The node sends
its hold command just before closed loop: the measured position, or standing still."""
import struct

from iotad.can.odrive import AXIS_STATE

from motor_bench import SET_AXIS_STATE, SET_INPUT_POS, SET_INPUT_VEL, Bench, encoder, heartbeat

CLOSED_LOOP, IDLE = AXIS_STATE["CLOSED_LOOP_CONTROL"], AXIS_STATE["IDLE"]


def test_the_motor_node_re_arms_with_a_hold_command_just_before_closed_loop():
    bench = Bench([{"name": "a", "node_id": 1}, {"name": "w", "node_id": 2, "mode": "velocity"}],
                  auto_rearm=True, arm_retry=0.1, polls={})
    bench.hear(0.005, encoder(1, 0.4, 0.0), encoder(2, 3.0, 0.0))
    bench.hear(0.02, heartbeat(1), heartbeat(2))           # ARMED
    bench.hear(0.05, heartbeat(1, IDLE), heartbeat(2, IDLE))  # a watchdog trip: DISARMED, re-armed later
    bench.run(0.3)
    again = [(ident, data) for t, ident, rtr, data in bench.sent(since=0.051) if not rtr]
    for node, hold in ((1, (1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 0.4, 0, 0))),   # where it was measured
                       (2, (2 << 5 | SET_INPUT_VEL, struct.pack("<ff", 0.0, 0.0)))):    # stand still
        mine = [frame for frame in again if frame[0] >> 5 == node]
        closed = mine.index((node << 5 | SET_AXIS_STATE, struct.pack("<I", CLOSED_LOOP) + bytes(4)))
        assert mine[closed - 1] == hold, mine
