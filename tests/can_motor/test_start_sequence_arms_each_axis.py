"""At start the node arms every axis with the same frames ros_odrive sends (and Set_Limits), byte
for byte, then waits for a closed-loop heartbeat; a time-out is reported and the arming retried."""
import math
import struct

from motor_bench import (CLEAR_ERRORS, CLOSED_LOOP, IDLE, SET_AXIS_STATE, SET_CONTROLLER_MODE, SET_INPUT_POS,
                      SET_INPUT_TORQUE, SET_INPUT_VEL, SET_LIMITS, SET_POS_GAIN, SET_TRAJ_ACCEL_LIMITS, SET_TRAJ_INERTIA, SET_TRAJ_VEL_LIMIT,
                      SET_VEL_GAINS, TAU, Bench, heartbeat, setpoints)


def arming(node: int, control_mode: int, input_mode: int, velocity_limit: float, current_limit: float):
    return [(node << 5 | CLEAR_ERRORS, False, bytes([0])),
            (node << 5 | SET_CONTROLLER_MODE, False, struct.pack("<II", control_mode, input_mode)),
            (node << 5 | SET_LIMITS, False, struct.pack("<ff", velocity_limit, current_limit)),
            (node << 5 | SET_AXIS_STATE, False, struct.pack("<I", CLOSED_LOOP) + bytes(4))]


def test_start_sequence_byte_for_byte(bench):
    bench.run(0.0)
    sent = bench.sent()
    assert all(t == 0.0 for t, *_ in sent)
    expected = (arming(1, 3, 1, math.pi / TAU, 10.0)           # position, PASSTHROUGH, pi rad/s, 10 A
                + arming(2, 3, 1, 9.0 * 2.0 / TAU, 10.0)        # gear 9: 2 rad/s at the joint
                + arming(5, 3, 1, math.pi / TAU, 10.0))
    assert [(ident, rtr, data) for _, ident, rtr, data in sent] == expected
    # Set_Axis_State goes out with the DLC of the DBC (8), zero-padded
    assert len(sent[3][3]) == 8  # no hold command: a position axis not yet measured (see below)
    assert [s["event"] for s in bench.status()] == ["ARM_SENT"] * 3
    assert [s["phase"] for s in bench.status()] == ["ARMING"] * 3


def test_modes_gains_and_trajectory_limits_go_out_before_closed_loop():
    bench = Bench([{"name": "a", "node_id": 3, "mode": "velocity", "input_mode": "VEL_RAMP",
                    "velocity_limit": TAU, "current_limit": 4.5, "pos_gain": 20.0, "vel_gain": 0.16,
                    "vel_integrator_gain": 0.32, "traj_vel_limit": 2.0, "traj_accel_limit": 1.0,
                    "traj_decel_limit": 1.5, "traj_inertia": 0.0},
                   {"name": "b", "node_id": 4, "mode": "torque", "input_mode": "TORQUE_RAMP"}])
    bench.run(0.0)
    sent = [(ident, data) for _, ident, _, data in bench.sent()]
    a = 3 << 5
    assert sent[:10] == [(a | CLEAR_ERRORS, b"\x00"),
                        (a | SET_CONTROLLER_MODE, struct.pack("<II", 2, 2)),
                        (a | SET_LIMITS, struct.pack("<ff", 1.0, 4.5)),
                        (a | SET_POS_GAIN, struct.pack("<f", 20.0) + bytes(4)),
                        (a | SET_VEL_GAINS, struct.pack("<ff", 0.16, 0.32)),
                        (a | SET_TRAJ_VEL_LIMIT, struct.pack("<f", 2.0) + bytes(4)),
                        (a | SET_TRAJ_ACCEL_LIMITS, struct.pack("<ff", 1.0, 1.5)),
                        (a | SET_TRAJ_INERTIA, struct.pack("<f", 0.0) + bytes(4)),
                        (a | SET_INPUT_VEL, struct.pack("<ff", 0.0, 0.0)),  # stand still, no torque
                        (a | SET_AXIS_STATE, struct.pack("<I", 8) + bytes(4))]
    b = 4 << 5
    assert sent[11] == (b | SET_CONTROLLER_MODE, struct.pack("<II", 1, 6))  # torque, TORQUE_RAMP
    assert sent[13:15] == [(b | SET_INPUT_TORQUE, struct.pack("<f", 0.0) + bytes(4)),  # no torque
                           (b | SET_AXIS_STATE, struct.pack("<I", 8) + bytes(4))]


def test_no_setpoint_goes_out_before_the_heartbeat_shows_closed_loop(bench):
    bench.post("setpoints", setpoints(3, [0.1, 0.2, 0.3]), t=0.01)
    bench.hear(0.02, heartbeat(1, IDLE), heartbeat(2, CLOSED_LOOP), heartbeat(5, IDLE))
    bench.post("setpoints", setpoints(3, [0.1, 0.2, 0.3]), t=0.03)
    bench.run(0.05)
    commands = [(t, ident) for t, ident, _, _ in bench.sent(since=0.001)]
    assert commands == [(0.03, 2 << 5 | SET_INPUT_POS)]  # only the armed axis, only after its heartbeat
    assert [(s["joint"], s["event"], s["phase"]) for s in bench.status(event="ARM_DONE")] == [(1, "ARM_DONE", "ARMED")]
    assert [s["phase"] for s in bench.status(joint=0)] == ["ARMING", "ARMING"]  # ARM_SENT, then a HEARTBEAT


def test_arming_time_out_is_reported_and_retried():
    bench = Bench([{"name": "j", "node_id": 1}], arm_timeout=0.5, arm_retry=0.25, polls={})
    for k in range(1, 20):  # the axis is alive but never enters closed loop (it keeps refusing)
        bench.hear(0.1 * k, heartbeat(1, IDLE, procedure=3))
    bench.hear(1.6, heartbeat(1, CLOSED_LOOP))
    bench.run(1.65)
    times = sorted({t for t, *_ in bench.sent()})
    assert times == [0.0, 0.75, 1.5]  # start; timeout at 0.5 + retry 0.25; timeout at 1.25 + 0.25
    assert [(s["t"], s["event"]) for s in bench.status() if s["event"] != "HEARTBEAT"] == [
        (0.0, "ARM_SENT"), (0.5, "ARM_TIMEOUT"), (0.75, "ARM_SENT"), (1.25, "ARM_TIMEOUT"), (1.5, "ARM_SENT"),
        (1.6, "ARM_DONE")]
    first = [frame[1:] for frame in bench.sent(until=0.0)]
    assert [frame[1:] for frame in bench.sent(since=0.7, until=0.8)] == first  # the same sequence again
