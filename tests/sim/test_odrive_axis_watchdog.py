"""The firmware watchdog of a simulated axis: every frame to the axis feeds it, remote polls
included (as the firmware's CAN handler does), and an armed axis left without one longer than
watchdog_timeout goes IDLE with WATCHDOG_TIMER_EXPIRED."""
from iotad.can import odrive
from iotad.can.odrive import AXIS_ERROR, AXIS_STATE
from sim.odrive_axis import AxisConfig, OdriveAxis

from sim_helpers import DT, command, poll

WATCHDOG = AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]
CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]


def armed(timeout=0.05):
    axis = OdriveAxis(1, AxisConfig(watchdog_timeout=timeout))
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    return axis


def first_idle_time(axis, until, commands=(), polls=()):
    """Step the axis every DT; send Set_Input_Pos at `commands` times, Get_Error polls at `polls`."""
    commands, polls = list(commands), list(polls)
    for k in range(1, round(until / DT) + 1):
        t = k * DT
        while commands and commands[0] <= t:
            axis.handle(command(1, "Set_Input_Pos", Input_Pos=0.0), commands.pop(0))
        while polls and polls[0] <= t:
            axis.handle(poll(1, "Get_Error"), polls.pop(0))
        if axis.update(0.0, 0.0, t, DT) is None:
            return t
    return None


def test_no_command_trips_the_watchdog_within_one_step_of_the_timeout():
    axis = armed(0.05)
    t = first_idle_time(axis, 1.0)
    assert 0.05 < t <= 0.05 + DT
    beat = odrive.decode(axis.heartbeat()).signals
    assert beat["Axis_State"] == AXIS_STATE["IDLE"] and beat["Axis_Error"] == WATCHDOG
    assert odrive.decode(axis.handle(poll(1, "Get_Error"), t)[0]).signals["Disarm_Reason"] == WATCHDOG


def test_commands_feed_it_and_it_trips_after_the_last_one():
    axis = armed(0.05)
    sends = [0.02 * k for k in range(1, 26)]  # every 20 ms until 0.5 s
    t = first_idle_time(axis, 1.0, commands=sends)
    assert 0.5 + 0.05 - 1e-9 < t <= 0.5 + 0.05 + DT


def test_remote_polls_feed_it_as_the_firmwares_can_handler_does():
    # can_simple.cpp's do_command feeds the watchdog before it looks at the command: a host (or a
    # bystander) that polls an axis keeps it armed; the axis trips once the polls stop too
    axis = armed(0.05)
    t = first_idle_time(axis, 1.0, polls=[0.01 * k for k in range(1, 51)])  # every 10 ms until 0.5 s
    assert 0.5 + 0.05 - 1e-9 < t <= 0.5 + 0.05 + DT


def test_timeout_zero_is_off_and_an_idle_axis_never_trips():
    assert first_idle_time(armed(0.0), 2.0) is None
    idle = OdriveAxis(1, AxisConfig(watchdog_timeout=0.05))
    for k in range(100):
        idle.update(0.0, 0.0, k * DT, DT)
    assert idle.axis_error == 0


def test_rearming_after_clear_errors_feeds_it_again():
    axis = armed(0.05)
    assert first_idle_time(axis, 1.0) is not None
    axis.handle(command(1, "Clear_Errors"), 1.0)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 1.0)
    assert axis.armed and axis.axis_error == 0
    assert axis.update(0.0, 0.0, 1.0 + 0.04, DT) is not None  # within the timeout of arming
    assert axis.update(0.0, 0.0, 1.0 + 0.06, DT) is None
