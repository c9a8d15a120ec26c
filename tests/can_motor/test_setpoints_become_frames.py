"""Each setpoints message becomes one command frame per armed axis, in the joint's mode, with
direction, gear ratio and offset applied: turns = direction * gear * (q - offset) / 2pi."""
import struct

import pytest

from motor_bench import SET_INPUT_POS, SET_INPUT_TORQUE, SET_INPUT_VEL, TAU, Bench, setpoints


def test_position_setpoint_bytes_with_direction_gear_and_offset(bench):
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(3, [0.7, 1.2, -0.4], velocity_ff=[0.5, -1.0, 0.25],
                                      torque_ff=[0.2, 1.8, -0.05]), t=0.06)
    bench.run(0.06)
    sent = [(ident, data) for _, ident, _, data in bench.sent(since=0.06)]
    # elbow: direction -1, gear 9, offset 0.5 rad; torque to the motor is divided by the gear
    elbow_turns = -1 * 9.0 * (1.2 - 0.5) / TAU
    assert sent == [
        (1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 0.7 / TAU, round(0.5 / TAU * 1000), 200)),
        (2 << 5 | SET_INPUT_POS, struct.pack("<fhh", elbow_turns, round(-1 * 9.0 * -1.0 / TAU * 1000),
                                             round(-1 * 1.8 / 9.0 * 1000))),
        (5 << 5 | SET_INPUT_POS, struct.pack("<fhh", -0.4 / TAU, round(0.25 / TAU * 1000), -50)),
    ]


def test_velocity_and_torque_modes_send_their_own_commands():
    bench = Bench([{"name": "wheel", "node_id": 7, "mode": "velocity", "direction": -1, "gear_ratio": 2.0,
                    "velocity_limit": 10.0},
                   {"name": "gripper", "node_id": 8, "mode": "torque", "gear_ratio": 4.0, "torque_limit": 6.0}])
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(2, position=[9.0, 9.0], velocity_ff=[3.0, 9.0], torque_ff=[0.4, 2.0]), t=0.06)
    bench.run(0.06)
    sent = [(ident, data) for _, ident, _, data in bench.sent(since=0.06)]
    assert sent == [
        # velocity: Input_Vel = -1 * 2 * 3 / 2pi turns/s, Input_Torque_FF = -1 * 0.4 / 2 Nm
        (7 << 5 | SET_INPUT_VEL, struct.pack("<ff", -2.0 * 3.0 / TAU, -0.4 / 2.0)),
        # torque: Input_Torque = 2.0 / 4 Nm at the motor; DLC 8 as the DBC gives
        (8 << 5 | SET_INPUT_TORQUE, struct.pack("<f", 0.5) + bytes(4)),
    ]


def test_every_setpoint_is_sent_a_steady_stream_for_the_watchdog(bench):
    bench.arm_all(0.05)
    for k in range(100):  # 500 Hz for 0.2 s
        bench.post("setpoints", setpoints(3, [0.001 * k] * 3), t=0.1 + 0.002 * k)
    bench.run(0.4)
    commands = [(t, ident) for t, ident, _, _ in bench.sent(since=0.1) if ident & 0x1F == SET_INPUT_POS]
    assert len(commands) == 300
    assert [t for t, _ in commands[::3]] == [0.1 + 0.002 * k for k in range(100)]  # same instant as the input
    assert not bench.violations()


def test_feed_forward_saturates_to_the_limits_and_the_frame_range():
    bench = Bench([{"name": "j", "node_id": 1, "gear_ratio": 100.0, "velocity_limit": 3.0, "torque_limit": 50.0}])
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(1, [0.0], velocity_ff=[-9.0], torque_ff=[-80.0]), t=0.06)
    bench.run(0.06)
    (_, _, _, data), = bench.sent(since=0.06)
    _, vel_ff, torque_ff = struct.unpack("<fhh", data)
    # -9 rad/s -> the joint limit -3 rad/s -> 100 * -3 / 2pi = -47.7 turns/s -> int16 x 0.001 floor
    assert vel_ff == -32767
    assert torque_ff == round(-50.0 / 100.0 * 1000)
    assert not bench.status(event="SETPOINT_CLAMPED")  # feed-forward is not the command: no report


@pytest.mark.parametrize("mode,field", [("position", 0), ("velocity", 1), ("torque", 2)])
def test_the_mode_picks_which_field_is_the_command(mode, field):
    bench = Bench([{"name": "j", "node_id": 1, "mode": mode}])
    bench.arm_all(0.05)
    values = [[0.1], [0.2], [0.3]]
    bench.post("setpoints", setpoints(1, *values), t=0.06)
    bench.run(0.06)
    (_, ident, _, data), = bench.sent(since=0.06)
    assert ident & 0x1F == (SET_INPUT_POS, SET_INPUT_VEL, SET_INPUT_TORQUE)[field]
    commanded = struct.unpack("<f", data[:4])[0]
    expected = values[field][0] / (TAU if field < 2 else 1.0)
    assert commanded == pytest.approx(expected, rel=1e-6)
