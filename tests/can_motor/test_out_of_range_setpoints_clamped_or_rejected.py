"""A setpoint outside the joint's limits is clamped or rejected as its `out_of_range` says, and
reported on joint_status with what was asked and what the axis now follows."""
import math
import struct

from motor_bench import SET_INPUT_POS, SET_INPUT_VEL, TAU, Bench, setpoints


def commands(bench, since):
    return {ident >> 5: struct.unpack("<f", data[:4])[0] for _, ident, _, data in bench.sent(since=since)
            if ident & 0x1F in (SET_INPUT_POS, SET_INPUT_VEL)}


def test_clamped_to_the_limit_and_reported(bench):
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(3, [0.1, 2.5, 0.2]), t=0.06)   # elbow max 2.0, clamp
    bench.run(0.06)
    sent = commands(bench, 0.06)
    assert sent[2] == struct.unpack("<f", struct.pack("<f", -9.0 * (2.0 - 0.5) / TAU))[0]
    (report,) = bench.status(event="SETPOINT_CLAMPED")
    assert (report["t"], report["joint"], report["requested"], report["applied"]) == (0.06, 1, 2.5, 2.0)


def test_rejected_setpoint_is_not_sent_and_the_last_one_holds(bench):
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(3, [0.1, 0.2, 0.3]), t=0.06)
    bench.post("setpoints", setpoints(3, [0.1, 0.2, -1.5]), t=0.07)   # wrist min -1.0, reject
    bench.run(0.07)
    assert sorted(commands(bench, 0.07)) == [1, 2]                      # nothing to the wrist (node 5)
    (report,) = bench.status(event="SETPOINT_REJECTED")
    assert (report["t"], report["joint"], report["requested"], report["applied"]) == (0.07, 2, -1.5, 0.3)


def test_not_finite_is_always_rejected(bench):
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(3, [math.inf, -math.inf, 0.0]), t=0.06)
    bench.run(0.06)
    assert sorted(commands(bench, 0.06)) == [5]
    reports = bench.status(event="SETPOINT_REJECTED")
    assert [(r["joint"], r["requested"]) for r in reports] == [(0, 1.7976931348623157e308), (1, -1.7976931348623157e308)]
    assert not bench.violations()


def test_velocity_mode_limits_the_velocity():
    bench = Bench([{"name": "w", "node_id": 1, "mode": "velocity", "velocity_limit": 1.0, "out_of_range": "clamp"},
                   {"name": "v", "node_id": 2, "mode": "velocity", "velocity_limit": 1.0}])
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(2, velocity_ff=[-3.0, 3.0]), t=0.06)
    bench.run(0.06)
    assert commands(bench, 0.06) == {1: struct.unpack("<f", struct.pack("<f", -1.0 / TAU))[0]}
    assert [(s["joint"], s["event"]) for s in bench.status() if s["event"].startswith("SETPOINT")] == [
        (0, "SETPOINT_CLAMPED"), (1, "SETPOINT_REJECTED")]


def test_a_huge_position_with_no_limits_is_rejected_not_a_crash():
    bench = Bench([{"name": "j", "node_id": 1}])
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(1, [1e300]), t=0.06)  # no float32 holds 1e300 / 2pi turns
    bench.run(0.06)
    assert commands(bench, 0.06) == {}
    assert [s["event"] for s in bench.status()][-1] == "SETPOINT_REJECTED"
    assert not bench.violations()


def test_an_infinite_feed_forward_is_rejected_not_sent_as_full_torque():
    """+-inf passes the channel's type (a Float may be infinite); saturated it would go out as the
    frame's largest torque feed-forward, or as a signal the controller drops with the command."""
    bench = Bench([{"name": "p", "node_id": 1}, {"name": "v", "node_id": 2, "mode": "velocity"},
                   {"name": "q", "node_id": 3}])
    bench.arm_all(0.05)
    bench.post("setpoints", setpoints(3, [0.1, 0.0, 0.2], velocity_ff=[0.0, 0.5, math.inf],
                                      torque_ff=[math.inf, -math.inf, 0.0]), t=0.06)
    bench.run(0.06)
    assert commands(bench, 0.06) == {}
    assert [(s["joint"], s["event"]) for s in bench.status() if s["event"].startswith("SETPOINT")] == [
        (0, "SETPOINT_REJECTED"), (1, "SETPOINT_REJECTED"), (2, "SETPOINT_REJECTED")]
    assert not bench.violations()
