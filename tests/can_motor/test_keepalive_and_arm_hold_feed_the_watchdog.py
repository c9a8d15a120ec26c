"""The node feeds the firmware watchdog: an ARMING axis gets "hold where you are" every arm_hold,
an ARMED axis with no setpoint for keepalive gets its last command again, without feed-forward."""
import struct

import pytest

from motor_bench import SET_INPUT_POS, SET_INPUT_TORQUE, SET_INPUT_VEL, Bench, encoder, heartbeat, setpoints

JOINTS = [{"name": "a", "node_id": 1, "gear_ratio": 2.0}, {"name": "w", "node_id": 2, "mode": "velocity"}]


def commands(bench, since=0.001):
    """The setpoint frames sent from `since` on (by default after the arming frames at 0, which
    end with a velocity joint's hold command)."""
    return [(round(t, 9), ident, data) for t, ident, rtr, data in bench.sent(since=since)
            if not rtr and ident & 0x1F in (SET_INPUT_POS, SET_INPUT_VEL)]


def test_arm_hold_then_keepalive_exact_frames():
    bench = Bench(JOINTS, keepalive=0.05, arm_hold=0.03, polls={})
    bench.hear(0.005, encoder(1, 0.4, 0.1), encoder(2, 7.0, 0.0))
    bench.hear(0.045, heartbeat(1), heartbeat(2))
    bench.post("setpoints", setpoints(2, [0.5, 0.0], velocity_ff=[0.2, 1.5], torque_ff=[0.1, 0.0]), t=0.055)
    bench.run(0.125)
    hold_a = struct.pack("<fhh", 0.4, 0, 0)           # the measured 0.4 turns, no feed-forward
    hold_w = struct.pack("<ff", 0.0, 0.0)             # velocity mode: hold = stand still
    assert commands(bench) == [
        (0.03, 1 << 5 | SET_INPUT_POS, hold_a), (0.03, 2 << 5 | SET_INPUT_VEL, hold_w),   # ARMING, tick 3
        (0.055, 1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 2.0 * 0.5 / 6.283185307179586,
                                                    round(2.0 * 0.2 / 6.283185307179586 * 1000), 50)),
        (0.055, 2 << 5 | SET_INPUT_VEL, struct.pack("<ff", 1.5 / 6.283185307179586, 0.0)),
        # ARMED, no setpoint since tick 5: the last command again at tick 10, feed-forward dropped
        (0.1, 1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 2.0 * 0.5 / 6.283185307179586, 0, 0)),
        (0.1, 2 << 5 | SET_INPUT_VEL, struct.pack("<ff", 1.5 / 6.283185307179586, 0.0)),
    ]


def test_no_hold_before_the_position_is_known_and_none_to_a_lost_axis():
    bench = Bench([{"name": "a", "node_id": 1}], keepalive=0.05, arm_hold=0.02, polls={})
    bench.hear(0.035, encoder(1, 0.25))
    bench.run(0.5)
    holds = [t for t, *_ in commands(bench)]
    assert holds[0] == 0.04                  # the first tick at arm_hold's pace once the position is known
    assert holds[-1] < 0.3 + 1e-9            # lost at 0.3 (no heartbeat ever): no more holds


@pytest.mark.parametrize("mode, command", [("velocity", SET_INPUT_VEL), ("torque", SET_INPUT_TORQUE)])
def test_an_armed_velocity_or_torque_joint_is_kept_standing_still_not_at_its_position(mode, command):
    """Holding still is, for a velocity or torque joint, 0 velocity or torque, not its position
    (0.5 turns here) taken for one: in the arming frames, and in the keep-alive."""
    bench = Bench([{"name": "w", "node_id": 1, "mode": mode}], keepalive=0.05, polls={})
    bench.hear(0.005, encoder(1, 0.5, 0.0))
    bench.hear(0.015, heartbeat(1))
    bench.run(0.125)
    sent = [(round(t, 9), data) for t, ident, rtr, data in bench.sent() if ident == 1 << 5 | command]
    assert sent[0][0] == 0.0  # the hold command before closed loop
    assert len(sent) == 3 and all(not any(data) for _, data in sent)  # 0.0 (and 0 feed-forward)
