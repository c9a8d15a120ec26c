"""The cascaded position -> velocity -> torque loop of a simulated axis, its input modes and limits,
driving a one-inertia plant in the axis's units (turns, turns/s, Nm)."""
import pytest

from iotad.can import odrive
from iotad.can.odrive import AXIS_ERROR, CONTROL_MODE, INPUT_MODE
from sim.odrive_axis import AxisConfig, OdriveAxis

from sim_helpers import DT, command, poll, run

POSITION, VELOCITY, TORQUE = CONTROL_MODE["POSITION"], CONTROL_MODE["VELOCITY"], CONTROL_MODE["TORQUE"]


def mode(axis, control, input_mode):
    axis.handle(command(axis.node_id, "Set_Controller_Mode", Control_Mode=control,
                        Input_Mode=INPUT_MODE[input_mode]), 0.0)


def test_position_passthrough_reaches_the_target(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=0.5), 0.0)
    run(axis, plant, 0.0, 1.5)
    assert plant.position == pytest.approx(0.5, abs=1e-4) and abs(plant.velocity) < 1e-3


def test_integrator_removes_the_error_of_a_constant_load(armed_axis):
    axis, plant = armed_axis
    plant.load = -0.8  # Nm, like gravity on a joint
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=0.2), 0.0)
    run(axis, plant, 0.0, 3.0)
    assert plant.position == pytest.approx(0.2, abs=1e-4)
    assert axis.integrator == pytest.approx(0.8, rel=1e-2)


def test_velocity_limit_caps_the_speed_of_a_position_move(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Limits", Velocity_Limit=0.5, Current_Limit=5.0), 0.0)
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=10.0), 0.0)
    speeds = []
    run(axis, plant, 0.0, 2.0, feed=lambda t: speeds.append(plant.velocity))
    # the velocity PI loop overshoots a little on the way in, then holds the limit
    assert max(speeds) < 0.5 * 1.2 and speeds[-1] == pytest.approx(0.5, rel=1e-3)


def test_current_limit_times_torque_constant_caps_the_torque(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Limits", Velocity_Limit=100.0, Current_Limit=0.4), 0.0)
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=5.0), 0.0)
    torques = run(axis, plant, 0.0, 0.5)
    assert max(abs(t) for t in torques) == pytest.approx(0.4)


def test_velocity_mode_tracks_the_input_and_its_torque_feed_forward(armed_axis):
    axis, plant = armed_axis
    mode(axis, VELOCITY, "PASSTHROUGH")
    axis.handle(command(3, "Set_Input_Vel", Input_Vel=1.25, Input_Torque_FF=0.0), 0.0)
    run(axis, plant, 0.0, 1.0)
    assert plant.velocity == pytest.approx(1.25, abs=1e-3)
    axis.handle(command(3, "Set_Input_Vel", Input_Vel=0.0, Input_Torque_FF=0.3), 1.0)
    assert axis.update(plant.position, 0.0, 1.0, DT) == pytest.approx(0.3 + axis.integrator)


def test_vel_ramp_changes_speed_at_the_ramp_rate(armed_axis):
    axis, plant = armed_axis
    mode(axis, VELOCITY, "VEL_RAMP")
    axis.handle(command(3, "Set_Input_Vel", Input_Vel=2.0), 0.0)
    setpoints = []
    run(axis, plant, 0.0, 1.0, feed=lambda t: setpoints.append(axis.vel_setpoint))
    # default vel_ramp_rate 1 turn/s^2: after 1 s the setpoint is at 1, not 2
    assert setpoints[-1] == pytest.approx(1.0 - DT, abs=1e-9)
    assert all(b - a <= 1.0 * DT + 1e-12 for a, b in zip(setpoints, setpoints[1:]))


def test_pos_filter_moves_smoothly_without_overshoot(armed_axis):
    axis, plant = armed_axis
    mode(axis, POSITION, "POS_FILTER")
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=1.0), 0.0)
    setpoints = []
    run(axis, plant, 0.0, 5.0, feed=lambda t: setpoints.append(axis.pos_setpoint))
    assert setpoints[0] < 0.01  # a step input, filtered
    assert max(setpoints) <= 1.0 + 1e-6 and setpoints[-1] == pytest.approx(1.0, abs=1e-3)
    assert plant.position == pytest.approx(1.0, abs=2e-3)


def test_torque_mode_passes_torque_and_cuts_it_near_the_velocity_limit(armed_axis):
    axis, plant = armed_axis
    mode(axis, TORQUE, "PASSTHROUGH")
    axis.handle(command(3, "Set_Input_Torque", Input_Torque=0.1), 0.0)
    assert axis.update(0.0, 0.0, 0.0, DT) == pytest.approx(0.1)
    # at the velocity limit (5 turn/s) no more torque pushes it faster
    assert axis.update(0.0, 5.0, 0.0, DT) == pytest.approx(0.0)
    run(axis, plant, 0.0, 3.0)
    assert plant.velocity <= 5.0 + 1e-6 and axis.integrator == 0.0


def test_torque_ramp_ramps_the_torque(armed_axis):
    axis, plant = armed_axis
    mode(axis, TORQUE, "TORQUE_RAMP")
    axis.handle(command(3, "Set_Input_Torque", Input_Torque=1.0), 0.0)
    axis.update(0.0, 0.0, 0.0, DT)
    assert axis.torque_setpoint == pytest.approx(0.01 * DT)  # default torque_ramp_rate 0.01 Nm/s


def test_gains_over_can_change_the_loop(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Pos_Gain", Pos_Gain=2.0), 0.0)
    axis.handle(command(3, "Set_Vel_Gains", Vel_Gain=0.5, Vel_Integrator_Gain=0.0), 0.0)
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=0.1), 0.0)
    # vel wanted = 2 * 0.1 = 0.2 turn/s; torque = 0.5 * 0.2
    assert axis.update(0.0, 0.0, 0.0, DT) == pytest.approx(0.1)


def test_set_absolute_position_moves_the_frame_without_a_jump(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=0.0), 0.0)
    run(axis, plant, 0.0, 0.5)
    axis.handle(command(3, "Set_Absolute_Position", Position=10.0), 0.5)
    assert axis.pos_estimate == pytest.approx(10.0) and axis.input_pos == pytest.approx(10.0, abs=1e-3)
    torques = run(axis, plant, 0.5, 0.5)
    assert max(abs(t) for t in torques) < 1e-2 and axis.pos_estimate == pytest.approx(10.0, abs=1e-3)
    (frame,) = axis.handle(poll(3, "Get_Encoder_Estimates"), 1.0)
    assert odrive.decode(frame).signals["Pos_Estimate"] == pytest.approx(10.0, abs=1e-3)


def test_overspeed_error_when_enabled():
    axis = OdriveAxis(1, AxisConfig(enable_overspeed_error=True, vel_limit=1.0))
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=8), 0.0)
    assert axis.update(0.0, 1.1, 0.0, DT) is not None
    assert axis.update(0.0, 1.3, 0.0, DT) is None
    assert axis.axis_error == AXIS_ERROR["VELOCITY_LIMIT_VIOLATION"]
