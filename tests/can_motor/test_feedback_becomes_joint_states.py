"""Encoder estimates, torques and the axis's other messages become joint states (joint units) and
status; remote requests poll what is not cyclic."""
import struct

import pytest

from motor_bench import (GET_ERROR, GET_TORQUES, IDLE, SET_AXIS_STATE, TAU, Bench, can, encoder, f32, heartbeat)


def test_encoder_estimates_become_joint_states_in_joint_units(bench):
    bench.hear(0.005, encoder(1, 0.25, -0.5), encoder(2, -1.5, 0.9), encoder(5, 0.125, 0.0))
    bench.run(0.02)
    states = bench.events("joint_states")
    assert [e["t"] for e in states] == [0.01, 0.02]  # every state_period (= encoder_period 0.01)
    value = states[0]["value"]
    # elbow: q = offset + direction * turns * 2pi / gear
    assert value["position"] == pytest.approx([0.25 * TAU, 0.5 + 1.5 * TAU / 9.0, 0.125 * TAU], abs=1e-12)
    assert value["velocity"] == pytest.approx([-0.5 * TAU, -0.9 * TAU / 9.0, 0.0], abs=1e-6)
    assert value["position"][1] == 0.5 + -1 * f32(-1.5) * TAU / 9.0  # exactly the inverse map
    assert value["stamp"] == 0.01


def test_no_joint_states_until_every_joint_has_reported_a_position(bench):
    bench.hear(0.005, encoder(1, 0.0), encoder(2, 0.0))
    bench.hear(0.035, encoder(5, 0.0))
    bench.run(0.05)
    assert [e["t"] for e in bench.events("joint_states")] == [0.04, 0.05]


def test_torques_give_the_effort_at_the_joint(bench):
    bench.hear(0.005, *(encoder(n, 0.0) for n in (1, 2, 5)))
    bench.hear(0.006, can(2, GET_TORQUES, struct.pack("<ff", 0.1, 0.25)))  # target, estimate (motor Nm)
    bench.run(0.01)
    effort = bench.events("joint_states")[0]["value"]["effort"]
    assert effort == [0.0, pytest.approx(-1 * 0.25 * 9.0), 0.0]


def test_get_error_is_polled_and_a_change_is_reported():
    bench = Bench(polls={"Get_Error": 0.05, "Get_Torques": 0.02})
    bench.hear(0.06, can(5, GET_ERROR, struct.pack("<II", 0x1000000, 0x1000000)))
    bench.hear(0.07, can(5, GET_ERROR, struct.pack("<II", 0x1000000, 0x1000000)))  # unchanged: no report
    bench.run(0.1)
    requests = [(t, ident) for t, ident, rtr, data in bench.sent(since=0.001) if rtr]
    errors = [(t, i) for t, i in requests if i & 0x1F == GET_ERROR]
    torques = [(t, i) for t, i in requests if i & 0x1F == GET_TORQUES]
    assert [t for t, _ in errors] == pytest.approx([0.05] * 3 + [0.1] * 3)
    assert [i >> 5 for _, i in errors[:3]] == [1, 2, 5]
    assert len(torques) == 5 * 3
    assert all(data == b"" for _, _, rtr, data in bench.sent() if rtr)  # remote frames, DLC 0
    (report,) = bench.status(event="ERRORS")
    assert (report["t"], report["joint"], report["active_errors"], report["disarm_reason"]) == (0.06, 2, 0x1000000, 0x1000000)


def test_heartbeat_fields_reach_the_status(bench):
    bench.hear(0.01, heartbeat(2, state=8, error=0x40, procedure=1, done=True))
    bench.run(0.01)
    events = bench.status(joint=1)
    # closed loop with an axis error is not armed: the node commands IDLE (issue 42)
    assert [s["event"] for s in events] == ["ARM_SENT", "AXIS_ERROR", "UNCOMMANDED_STATE"]
    last = events[-1]
    assert (last["axis_state"], last["axis_error"], last["procedure_result"], last["trajectory_done"],
            last["phase"], last["node_id"]) == (8, 0x40, 1, True, "ARMING", 2)
    idle = [data for t, ident, rtr, data in bench.sent(since=0.01) if ident == (2 << 5 | SET_AXIS_STATE)]
    assert idle == [struct.pack("<I", IDLE).ljust(8, b"\0")]
