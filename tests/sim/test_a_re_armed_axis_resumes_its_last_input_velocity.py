"""The firmware keeps an axis's input velocity and torque across IDLE (axis.cpp
start_closed_loop_control resets only a position input, to where the axis is), so an axis
re-armed after a watchdog trip, an estop reset or a restart of its host resumes the speed it was
last given; a host sends its hold command before closed loop (nodes/can_motor does:
tests/can_motor/test_re_arming_never_resumes_a_stale_command.py). The simulated axis does as the
firmware does, so that a host that forgets shows it in simulation."""
from iotad.can.odrive import AXIS_STATE, CONTROL_MODE, INPUT_MODE
from sim.odrive_axis import AxisConfig, OdriveAxis

from sim_helpers import DT, Inertia, command

CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]


def tripped_while_driving(speed: float):
    """A velocity-mode axis driven at `speed` turns/s until its watchdog (50 ms) trips."""
    axis = OdriveAxis(1, AxisConfig(watchdog_timeout=0.05, control_mode=CONTROL_MODE["VELOCITY"],
                                    input_mode=INPUT_MODE["PASSTHROUGH"]))
    plant = Inertia(0.01)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(1, "Set_Input_Vel", Input_Vel=speed, Input_Torque_FF=0.0), 0.0)
    t = 0.0
    while axis.armed:
        t += DT
        plant.step(axis.update(plant.position, plant.velocity, t, DT))
    plant.velocity = 0.0  # it coasted to a stop while IDLE
    return axis, plant, t


def speed_after_re_arming(axis, plant, t, before=()):
    for message in (*before, command(1, "Clear_Errors", Identify=0),
                    command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP)):
        axis.handle(message, t)
    for _ in range(24):  # 0.1 s
        t += DT
        axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), t)  # keeps it fed
        plant.step(axis.update(plant.position, plant.velocity, t, DT))
    return plant.velocity


def test_a_simulated_axis_re_armed_resumes_its_last_input_velocity_as_the_firmware_does():
    axis, plant, t = tripped_while_driving(2.0)
    assert axis.input_vel == 2.0 and not axis.armed
    assert speed_after_re_arming(axis, plant, t) > 1.0  # off it goes, toward 2 turns/s


def test_a_hold_command_before_closed_loop_keeps_it_still():
    axis, plant, t = tripped_while_driving(2.0)
    hold = command(1, "Set_Input_Vel", Input_Vel=0.0, Input_Torque_FF=0.0)
    assert abs(speed_after_re_arming(axis, plant, t, before=(hold,))) < 1e-6


