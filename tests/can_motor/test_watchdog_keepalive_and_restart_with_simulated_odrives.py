"""With the simulated ODrives (watchdog 80 ms, as the firmware's: no command within the timeout puts
the axis in IDLE with WATCHDOG_TIMER_EXPIRED): a silent setpoint source trips the axes' watchdog
unless the node's keep-alive feeds it, an axis armed without arm_hold trips before its heartbeat
can show closed loop, and a fresh node facing tripped axes clears their errors, re-arms them and
moves the arm. Times are measured from the frames the axes sent and received, in virtual time."""
import struct

import pytest

pytest.importorskip("pybullet")

from arm_system import HOME, arm_system  # noqa: E402
from iotad.can.odrive import AXIS_ERROR  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402

WATCHDOG = AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]
WATCHDOG_TIMEOUT = 0.08          # SimulatedOdrives' default
STEP = 1 / 240                   # its control step: the watchdog is checked once per step
HEARTBEAT_PERIOD = 0.1
IDLE, CLOSED_LOOP, SET_AXIS_STATE = 1, 8, 0x07
# Host commands of CAN Simple 0.6 (what feeds the firmware's watchdog): Estop, Set_Axis_State,
# Set_Controller_Mode, Set_Input_Pos/Vel/Torque, Set_Limits, Set_Traj_*, Clear_Errors, gains.
COMMANDS = {0x02, 0x07, 0x0B, 0x0C, 0x0D, 0x0E, 0x0F, 0x11, 0x12, 0x13, 0x18, 0x1A, 0x1B}
TARGET = (0.3, -0.1, -0.8, 0.2, 1.1, 0.3)


@pytest.fixture
def engines():
    made = []
    yield made
    for engine in made:
        engine.iota("arm/odrives").close()


def odrives_received(engine, node):
    """(t, frame) of every frame for `node` the simulated axes received."""
    return [(e["t"], e["value"]) for e in engine.trace if e["iota"] == "arm/odrives"
            and e["action"] == "can_rx" and e["value"]["id"] >> 5 == node]


def heartbeats(engine, node):
    """(t, axis state, axis error) of every Heartbeat of `node`, when the axis sent it."""
    out = []
    for e in engine.trace:
        frame = e["value"]
        if e["iota"] == "arm/odrives" and e["action"] == "can_tx" and frame["id"] == node << 5 | 0x01:
            error, state, _, _ = struct.unpack("<IBBBx", bytes(frame["data"]))
            out.append((e["t"], state, error))
    return out


def motor_status(engine, event=None):
    return [dict(e["value"], t=e["t"]) for e in engine.trace if e["iota"] == "arm/motor"
            and e["action"] == "joint_status" and (event is None or e["value"]["event"] == event)]


def test_keepalive_holds_an_armed_arm_when_its_source_falls_silent(engines):
    engine = Engine(arm_system(HOME, silent_after=0.3))
    engines.append(engine)
    engine.run(until=1.0)
    assert not motor_status(engine, "DISARMED")
    assert {s["phase"] for s in motor_status(engine)[-6:]} == {"ARMED"}
    positions, _ = engine.iota("arm/odrives").plant.read_joints()
    assert positions[:6] == pytest.approx(HOME, abs=0.01)  # holding where it was told


def test_without_keepalive_a_silent_source_trips_the_watchdog(engines):
    engine = Engine(arm_system(HOME, motor_params={"keepalive": 0.0}, silent_after=0.3))
    engines.append(engine)
    engine.run(until=1.0)
    disarmed = motor_status(engine, "DISARMED")
    assert sorted(s["joint"] for s in disarmed) == list(range(6))
    assert all(s["axis_error"] & WATCHDOG and s["phase"] == "FAULT" for s in disarmed)
    # Measured from the frames on the bus, per axis: the firmware trips `watchdog_timeout` after
    # the last frame it received (checked once per control step), and its cyclic heartbeat says
    # so at the next beat. Every frame to the axis feeds it, remote requests too (the node's
    # Get_Error polls, every 0.5 s: one that comes within the timeout of the last command, as
    # here at 79.9 ms, holds the axis one more poll period; the firmware's CAN handler feeds the
    # watchdog before it looks at the command).
    for node in range(1, 7):
        last_command = max(t for t, frame in odrives_received(engine, node)
                           if not frame["rtr"] and frame["id"] & 0x1F in COMMANDS)
        fed = [t for t, _ in odrives_received(engine, node) if t >= last_command]
        last_feed = next(t for t, later in zip(fed, fed[1:] + [float("inf")]) if later - t > WATCHDOG_TIMEOUT)
        trip = last_feed + WATCHDOG_TIMEOUT
        beats = heartbeats(engine, node)
        before = [(state, error) for t, state, error in beats if last_command - 0.2 < t < trip]
        after = [(t, state, error) for t, state, error in beats if t > trip + STEP]
        assert before and set(before) == {(CLOSED_LOOP, 0)}
        assert after and all(state == IDLE and error & WATCHDOG for _, state, error in after)
        assert after[0][0] <= trip + STEP + HEARTBEAT_PERIOD
        status = next(s for s in disarmed if s["node_id"] == node)
        assert after[0][0] <= status["t"] <= after[0][0] + 0.003  # the node reports it at once


def test_without_arm_hold_an_axis_whose_watchdog_beats_its_heartbeat_never_arms(engines):
    # Closed loop starts the watchdog; the node sends setpoints only once a heartbeat has shown
    # closed loop, so without arm_hold nothing feeds the watchdog between. The six axes' heartbeats
    # are staggered by 100/6 ms: with a 40 ms watchdog, an axis whose first beat comes within 40 ms
    # of its Set_Axis_State arms; the others trip first, and every retry trips the same way.
    engine = Engine(arm_system(HOME, motor_params={"keepalive": 0.0, "arm_hold": 0.0},
                               odrive_params={"watchdog_timeout": 0.04}))
    engines.append(engine)
    engine.run(until=1.05)
    beats_first = set()
    for node in range(1, 7):
        closed_loop = next(t for t, frame in odrives_received(engine, node)
                           if frame["id"] & 0x1F == SET_AXIS_STATE and frame["data"][0] == CLOSED_LOOP)
        first_beat = next(t for t, _, _ in heartbeats(engine, node) if t > closed_loop)
        margin = first_beat - closed_loop - 0.04
        assert abs(margin) > STEP  # no axis on the edge: the outcome is the firmware's, not a tie
        if margin < 0:
            beats_first.add(node - 1)
    assert beats_first == {0, 1}
    assert {s["joint"] for s in motor_status(engine, "ARM_DONE")} == beats_first
    timeouts = motor_status(engine, "ARM_TIMEOUT")
    assert sorted(s["joint"] for s in timeouts) == [2, 3, 4, 5]
    assert all(s["axis_error"] & WATCHDOG and s["axis_state"] == IDLE for s in timeouts)


def test_a_fresh_node_clears_tripped_axes_re_arms_and_moves(engines):
    engine = Engine(arm_system(TARGET, start=0.3, duration=1.0))
    engines.append(engine)
    odrives = engine.iota("arm/odrives")  # its world and axes exist once it is built
    for axis in odrives.axes:  # what a node killed mid-motion leaves behind
        axis.fault(WATCHDOG)
    assert all(axis.axis_error & WATCHDOG for axis in odrives.axes)
    engine.run(until=1.8)
    assert not any(axis.axis_error for axis in odrives.axes)  # cleared by the node
    assert all(axis.armed for axis in odrives.axes)
    first = {}
    for e in engine.trace:
        if e["iota"] == "arm/motor" and e["action"] == "can_tx":
            first.setdefault(e["value"]["id"] >> 5, e["value"]["id"] & 0x1F)
    assert first == {node: 0x18 for node in range(1, 7)}  # Clear_Errors is each axis's first frame
    done = motor_status(engine, "ARM_DONE")
    assert sorted(s["joint"] for s in done) == list(range(6))
    assert all(s["axis_error"] == 0 for s in done)
    final = [e for e in engine.trace if e["action"] == "joint_states"][-1]["value"]["position"]
    assert final == pytest.approx(TARGET, abs=0.01)


def test_skipping_unchanged_setpoints_holds_an_armed_arm_on_fewer_frames(engines):
    """The source repeats the target at every tick once there (trajectory's end at 0.3 s); with
    `skip_unchanged` only the keep-alive (every 0.05 s) feeds the watchdog (80 ms), and the axes
    stay armed and where they were told."""
    received = {}
    for skip in (False, True):
        engine = Engine(arm_system(HOME, motor_params={"skip_unchanged": skip}, duration=0.3))
        engines.append(engine)
        engine.run(until=1.5)
        assert not motor_status(engine, "DISARMED")
        positions, _ = engine.iota("arm/odrives").plant.read_joints()
        assert positions[:6] == pytest.approx(HOME, abs=0.01)
        received[skip] = [t for node in range(1, 7) for t, frame in odrives_received(engine, node)
                          if not frame["rtr"] and frame["id"] & 0x1F == 0x0C and t > 0.5]
    assert len(received[True]) < len(received[False]) / 2
