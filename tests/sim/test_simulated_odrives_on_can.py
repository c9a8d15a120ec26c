"""SimulatedOdrives in virtual time: the cyclic frames, an arm following a trajectory through CAN,
the watchdog when the commands stop, recovery, bad frames, and determinism."""
import math
import struct

import pytest

from iotad.can import odrive
from iotad.can.frame import Frame
from iotad.can.odrive import AXIS_ERROR, AXIS_STATE

from sim_helpers import TWO_PI

CLOSED_LOOP, IDLE = AXIS_STATE["CLOSED_LOOP_CONTROL"], AXIS_STATE["IDLE"]
WATCHDOG = AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]


def arm_all(sim, t, nodes):
    for node in nodes:
        sim.send(t, node, "Clear_Errors")
        sim.send(t, node, "Set_Controller_Mode", Control_Mode=3, Input_Mode=1)
        sim.send(t, node, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP)


def stream_trajectory(sim, nodes, start, goal, t0, duration, rate=100.0, hold=0.0, cut=None):
    """Set_Input_Pos (turns) with velocity feed-forward along a smooth (cosine) path, then hold;
    `cut`: the sender dies after that many seconds. The time of the last command."""
    steps = round((duration + hold if cut is None else cut) * rate)
    for k in range(steps + 1):
        t = t0 + k / rate
        s = min(1.0, (t - t0) / duration)
        blend = 0.5 - 0.5 * math.cos(math.pi * s)
        rate_of_blend = 0.0 if s >= 1 else 0.5 * math.pi * math.sin(math.pi * s) / duration
        for node, a, b in zip(nodes, start, goal):
            sim.send(t, node, "Set_Input_Pos", Input_Pos=(a + (b - a) * blend) / TWO_PI,
                     Vel_FF=(b - a) * rate_of_blend / TWO_PI, Torque_FF=0.0)
    return t0 + steps / rate


def test_each_axis_sends_heartbeat_every_100ms_and_estimates_every_10ms(make_sim):
    sim = make_sim(world="kuka")
    sim.run(2.0)
    for node in range(7):
        beats = [t for t, _ in sim.sent("Heartbeat", node)]
        estimates = [t for t, _ in sim.sent("Get_Encoder_Estimates", node)]
        assert len(beats) in (19, 20) and len(estimates) in (199, 200)
        assert all(b - a == pytest.approx(0.1) for a, b in zip(beats, beats[1:]))
        assert all(b - a == pytest.approx(0.01) for a, b in zip(estimates, estimates[1:]))
    # independent controllers are not in phase: the axes' heartbeats are spread over the period
    firsts = sorted(sim.sent("Heartbeat", node)[1][0] for node in range(7))
    assert len(set(round(t, 6) for t in firsts)) == 7
    assert not sim.violations()
    (_, beat) = sim.sent("Heartbeat", 0)[-1]
    assert beat.signals["Axis_State"] == IDLE and beat.signals["Axis_Error"] == 0


def test_xarm_follows_a_trajectory_through_can_to_within_0_01_rad(make_sim):
    sim = make_sim(world="arm")
    world = sim.iota.plant
    start, _ = world.read_joints()
    goal = [a + d for a, d in zip(start, (0.6, 0.3, -0.4, 0.8, -0.5, 1.2, 0.7))]
    nodes = list(range(7))
    arm_all(sim, 0.05, nodes)
    end = stream_trajectory(sim, nodes, start, goal, 0.1, 2.0, hold=0.5)
    sim.run(end)
    reached, _ = world.read_joints()
    assert max(abs(a - b) for a, b in zip(reached, goal)) < 0.01
    # and so say the encoder estimates on the bus, in turns
    for node, target in zip(nodes, goal):
        (_, last) = sim.sent("Get_Encoder_Estimates", node)[-1]
        assert last.signals["Pos_Estimate"] * TWO_PI == pytest.approx(target, abs=0.01)
    assert all(m.signals["Axis_State"] == CLOSED_LOOP for node in nodes for _, m in sim.sent("Heartbeat", node)[-1:])
    assert not sim.violations()


def test_commands_stop_every_axis_trips_its_watchdog_within_100ms_and_nothing_moves(make_sim):
    sim = make_sim(world="arm", watchdog_timeout=0.08)
    world = sim.iota.plant
    start, _ = world.read_joints()
    goal = [a + 0.5 for a in start[:6]] + [0.4]
    nodes = list(range(7))
    arm_all(sim, 0.05, nodes)
    # the motion is cut half-way: the commanding node dies
    last = stream_trajectory(sim, nodes, start, goal, 0.1, 2.0, cut=1.0)
    sim.run(last)
    assert all(axis.armed for axis in sim.iota.axes)
    # no frame reaches the axes any more (a poll would feed the watchdog, as the firmware's does)
    sim.run(last + 0.1)
    assert [(axis.armed, axis.disarm_reason) for axis in sim.iota.axes] == [(False, WATCHDOG)] * len(nodes)
    sim.run(last + 0.3)
    moving_at_cut, _ = world.read_joints()
    for node in nodes:
        beats = sim.sent("Heartbeat", node)
        assert all(m.signals["Axis_State"] == CLOSED_LOOP for t, m in beats if 0.2 < t <= last)
        assert beats[-1][1].signals["Axis_State"] == IDLE and beats[-1][1].signals["Axis_Error"] == WATCHDOG
    sim.run(last + 2.3)
    after, _ = world.read_joints()
    assert max(abs(a - b) for a, b in zip(moving_at_cut, after)) < 1e-3  # the brakes hold
    # a restarted commander clears the errors, re-arms the axes, and motion resumes
    here, _ = world.read_joints()
    arm_all(sim, last + 2.4, nodes)
    end = stream_trajectory(sim, nodes, here, goal, last + 2.45, 1.0, hold=0.5)
    sim.run(end)
    reached, _ = world.read_joints()
    assert max(abs(a - b) for a, b in zip(reached, goal)) < 0.01


def test_bad_frames_are_ignored_without_answer_or_violation(make_sim):
    sim = make_sim(world="buggy")
    bad = [Frame(0x7FF, bytes(8)),                                  # node 63: nobody here
           Frame(odrive.frame_id(0, 0x0C), struct.pack("<f", math.nan) + bytes(4)),  # Set_Input_Pos to NaN
           Frame(odrive.frame_id(1, 0x08), bytes(8)),               # cmd 0x08: no such message
           Frame(odrive.frame_id(0, 0x07), bytes(8), extended=True),  # an extended id
           Frame(0x123, b"\xff" * 8)]                               # garbage
    for k, frame in enumerate(bad):
        sim.post(0.01 * (k + 1), frame)
    sim.run(0.2)
    assert sim.iota.frames_ignored == len(bad) - 1  # not for an axis, or not understood
    assert "Input_Pos=nan is not a finite number" in sim.iota.axes[0].ignored[-1]  # axis 0 ignored it
    assert not sim.violations()
    assert {m.name for _, m in sim.sent()} == {"Heartbeat", "Get_Encoder_Estimates"}  # no answers
    assert all(axis.state == IDLE and axis.axis_error == 0 for axis in sim.iota.axes)


def test_a_run_is_deterministic(make_sim):
    traces = []
    for _ in range(2):
        sim = make_sim(world="arm", world_key=f"arm{len(traces)}")
        start, _ = sim.iota.plant.read_joints()
        arm_all(sim, 0.05, range(7))
        stream_trajectory(sim, range(7), start, [q + 0.3 for q in start], 0.1, 0.5)
        sim.run(0.7)
        traces.append(sim.engine.trace)
    assert traces[0] == traces[1] and len(traces[0]) > 500


def test_node_ids_and_gear_map_joints_to_axes(make_sim):
    sim = make_sim(world="buggy", node_ids={"drive": 12, "turn": 20}, gear={"drive": 4.0})
    assert sorted(sim.iota.by_node) == [12, 20]
    world = sim.iota.plant
    world.turn.position = 1.0  # heading 1 rad
    sim.run(0.05)
    (_, turn) = sim.sent("Get_Encoder_Estimates", 20)[-1]
    assert turn.signals["Pos_Estimate"] == pytest.approx(1.0 / TWO_PI)
    # gear 4: 4 motor turns per wheel turn, so the motor's limits and loop are scaled
    drive = sim.iota.axis("drive")
    assert drive.vel_limit == pytest.approx(world.velocity_limits()[0] * 4 / TWO_PI)
    assert drive.current_limit == pytest.approx(world.effort_limits()[0] / 4)


def test_buggy_actuators_in_velocity_mode_move_buggy(make_sim):
    sim = make_sim(world="buggy", control_mode="VELOCITY", watchdog_timeout=0,
                   world_options={"seed": 3, "start": (0.0, 0.0, 0.0)})
    world = sim.iota.plant
    for node in (0, 1):
        sim.send(0.01, node, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP)
    speed, turn_rate = 0.2, 0.5
    sim.send(0.02, 0, "Set_Input_Vel", Input_Vel=speed / world.wheel_radius / TWO_PI)
    sim.send(0.02, 1, "Set_Input_Vel", Input_Vel=turn_rate / TWO_PI)
    sim.run(2.0)
    assert world.speed() == pytest.approx(speed, rel=1e-3)
    assert world.turn.velocity == pytest.approx(turn_rate, rel=1e-3)
    assert 0.3 < world.distance < 0.4 and world.inside()


@pytest.mark.parametrize("params, message", [
    ({"world": "mars"}, "world 'mars' is not one of"),
    ({"step_period": 0}, "step_period must be a number > 0"),
    ({"watchdog_timeout": -1}, "watchdog_timeout must be a number >= 0"),
    ({"control_mode": "FAST"}, "control_mode 'FAST' is not one of"),
    ({"gains": {"joint1": {"kp": 1}}}, "gains.joint1: expected a table"),
    ({"node_ids": 3}, "node_ids must be a list"),
])
def test_bad_params_are_clear_errors_at_build_time(params, message):
    from sim.odrive_sim import SimulatedOdrives
    with pytest.raises(ValueError, match=message):
        SimulatedOdrives("sim", **params)


@pytest.mark.parametrize("params, message", [
    ({"node_ids": [1, 2]}, "node_ids has 2 ids for 7 joints"),
    ({"node_ids": {"elbow": 1}}, "joints the world does not have"),
    ({"node_ids": {"joint1": 1, "joint2": 1}}, "node ids must be distinct"),
    ({"gear": {"joint1": -2}}, "gear of joint1 must be a number > 0"),
    ({"gains": {"elbow": {"pos_gain": 1}}}, "gains/limits name joints the world does not have"),
    ({"world_options": {"colour": "red"}}, "world 'arm'"),
])
def test_bad_joint_maps_are_clear_errors_when_the_world_opens(params, message):
    from sim.odrive_sim import SimulatedOdrives
    from sim.worlds import find_world
    with pytest.raises(ValueError, match=message):
        SimulatedOdrives("sim", **params)
    assert find_world("sim") is None  # nothing left open
