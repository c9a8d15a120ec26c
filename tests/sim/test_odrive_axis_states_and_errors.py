"""One simulated ODrive axis: its state machine, error latching, Estop, Clear_Errors, Get_Error,
and the answers it gives to invalid requests, all through decoded CAN Simple messages."""
import math

import pytest

from iotad.can import odrive
from iotad.can.odrive import AXIS_ERROR, AXIS_STATE, PROCEDURE_RESULT
from sim.odrive_axis import AxisConfig, OdriveAxis

from sim_helpers import command, poll

IDLE, CLOSED_LOOP = AXIS_STATE["IDLE"], AXIS_STATE["CLOSED_LOOP_CONTROL"]


def heartbeat(axis):
    return odrive.decode(axis.heartbeat()).signals


def test_power_up_idle_then_closed_loop_holds_where_it_is():
    axis = OdriveAxis(1)
    axis.update(0.25, 0.0, 0.0, 0.004)
    assert heartbeat(axis) == {"Axis_Error": 0, "Axis_State": IDLE, "Procedure_Result": 0, "Trajectory_Done_Flag": 1}
    assert axis.update(0.25, 0.0, 0.0, 0.004) is None  # motor off while IDLE
    assert axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.01) == []
    assert heartbeat(axis)["Axis_State"] == CLOSED_LOOP
    assert axis.input_pos == 0.25 and axis.pos_setpoint == 0.25  # no jump on arming
    assert axis.update(0.25, 0.0, 0.02, 0.004) == 0.0


def test_idle_request_disarms_without_error():
    axis = OdriveAxis(1)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=IDLE), 0.1)
    assert heartbeat(axis)["Axis_State"] == IDLE and axis.axis_error == 0


def test_estop_disarms_with_estop_error_until_cleared():
    axis = OdriveAxis(2)
    axis.handle(command(2, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(2, "Estop"), 0.5)
    beat = heartbeat(axis)
    assert beat["Axis_State"] == IDLE and beat["Axis_Error"] == AXIS_ERROR["ESTOP_REQUESTED"]
    assert axis.update(0.0, 0.0, 0.6, 0.004) is None
    # closed loop is refused while the error is latched
    axis.handle(command(2, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.7)
    beat = heartbeat(axis)
    assert beat["Axis_State"] == IDLE and beat["Procedure_Result"] == PROCEDURE_RESULT["DISARMED"]
    axis.handle(command(2, "Clear_Errors", Identify=0), 0.8)
    assert heartbeat(axis)["Axis_Error"] == 0 and heartbeat(axis)["Axis_State"] == IDLE  # clearing does not arm
    axis.handle(command(2, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.9)
    assert heartbeat(axis)["Axis_State"] == CLOSED_LOOP


def test_get_error_answers_active_errors_and_disarm_reason():
    axis = OdriveAxis(4)
    reply = axis.handle(poll(4, "Get_Error"), 0.0)
    assert [odrive.decode(f).signals for f in reply] == [{"Active_Errors": 0, "Disarm_Reason": 0}]
    axis.handle(command(4, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(4, "Estop"), 0.1)
    (frame,) = axis.handle(poll(4, "Get_Error"), 0.2)
    assert frame.id == odrive.frame_id(4, "Get_Error") and not frame.rtr
    assert odrive.decode(frame).signals == {"Active_Errors": AXIS_ERROR["ESTOP_REQUESTED"],
                                            "Disarm_Reason": AXIS_ERROR["ESTOP_REQUESTED"]}


def test_unsupported_state_is_refused_with_invalid_state():
    axis = OdriveAxis(1)
    for state in ("SENSORLESS_CONTROL", "LOCKIN_SPIN", "HOMING", "UNDEFINED"):
        axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=AXIS_STATE[state]), 0.0)
        assert heartbeat(axis)["Procedure_Result"] == PROCEDURE_RESULT["INVALID_STATE"], state
        assert heartbeat(axis)["Axis_State"] == IDLE
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=99), 0.0)
    assert heartbeat(axis)["Procedure_Result"] == PROCEDURE_RESULT["INVALID_STATE"]


def test_calibration_requests_succeed_at_once():
    axis = OdriveAxis(1)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=AXIS_STATE["FULL_CALIBRATION_SEQUENCE"]), 0.0)
    assert heartbeat(axis) == {"Axis_Error": 0, "Axis_State": IDLE, "Procedure_Result": 0, "Trajectory_Done_Flag": 1}


def test_unsupported_controller_mode_is_a_bad_config_error_that_disarms():
    axis = OdriveAxis(5)
    axis.handle(command(5, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(5, "Set_Controller_Mode", Control_Mode=0, Input_Mode=1), 0.1)  # VOLTAGE
    beat = heartbeat(axis)
    assert beat["Axis_State"] == IDLE and beat["Axis_Error"] == AXIS_ERROR["BAD_CONFIG"]
    assert axis.control_mode == odrive.CONTROL_MODE["POSITION"]  # unchanged
    axis.handle(command(5, "Clear_Errors"), 0.2)
    axis.handle(command(5, "Set_Controller_Mode", Control_Mode=3, Input_Mode=7), 0.3)  # MIRROR
    assert heartbeat(axis)["Axis_Error"] == AXIS_ERROR["BAD_CONFIG"]


def test_non_finite_and_negative_values_are_ignored():
    axis = OdriveAxis(1)
    axis.handle(command(1, "Set_Input_Pos", Input_Pos=1.0), 0.0)
    axis.handle(command(1, "Set_Input_Pos", Input_Pos=math.nan), 0.1)
    axis.handle(command(1, "Set_Limits", Velocity_Limit=math.inf, Current_Limit=3.0), 0.1)
    axis.handle(command(1, "Set_Limits", Velocity_Limit=-1.0, Current_Limit=3.0), 0.1)
    assert axis.input_pos == 1.0 and axis.vel_limit == AxisConfig().vel_limit
    assert len(axis.ignored) == 3 and "nan" in axis.ignored[0]


def test_axis_messages_with_data_and_remote_commands_are_ignored():
    axis = OdriveAxis(1)
    # another device's heartbeat on our node id is not a command; a remote frame for a command asks nothing
    assert axis.handle(odrive.decode(odrive.encode(1, "Heartbeat", Axis_State=8)), 0.0) == []
    assert axis.handle(poll(1, "Set_Input_Pos"), 0.0) == []
    assert axis.state == IDLE and len(axis.ignored) == 2


def test_remote_requests_are_answered_with_decodable_frames():
    """Every Get_ message and Address, as ODrive's CAN protocol documents remote requests."""
    axis = OdriveAxis(7)
    axis.update(1.5, -0.25, 0.0, 0.004)
    answers = {}
    for name in ("Get_Encoder_Estimates", "Get_Error", "Get_Version", "Get_Iq", "Get_Torques",
                 "Get_Powers", "Get_Bus_Voltage_Current", "Get_Temperature", "Address"):
        (frame,) = axis.handle(poll(7, name), 0.0)
        message = odrive.decode(frame)
        assert message.name == name and message.node_id == 7 and not message.rtr
        answers[name] = message.signals
    # the protocol documents remote requests for the Get_ messages: Heartbeat is cyclic only
    assert axis.handle(poll(7, "Heartbeat"), 0.0) == [] and "Heartbeat" in axis.ignored[-1]
    assert answers["Get_Encoder_Estimates"] == {"Pos_Estimate": 1.5, "Vel_Estimate": -0.25}
    assert answers["Get_Version"]["Fw_Version_Minor"] == 6 and answers["Get_Version"]["Fw_Version_Revision"] == 10
    assert answers["Address"]["Node_ID"] == 7


def test_reboot_returns_to_power_up():
    axis = OdriveAxis(1, AxisConfig(vel_limit=3.0))
    axis.handle(command(1, "Set_Limits", Velocity_Limit=1.0, Current_Limit=2.0), 0.0)
    axis.handle(command(1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(1, "Reboot", Action=0), 0.1)
    assert axis.state == IDLE and axis.vel_limit == 3.0 and axis.current_limit == 10.0


def test_cyclic_frames_are_byte_for_byte_the_codecs():
    axis = OdriveAxis(9)
    axis.update(-2.75, 13.5, 0.0, 0.004)
    axis.handle(command(9, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP), 0.0)
    axis.handle(command(9, "Estop"), 0.0)
    assert axis.heartbeat() == odrive.encode(9, "Heartbeat", Axis_Error=axis.axis_error, Axis_State=1,
                                             Procedure_Result=0, Trajectory_Done_Flag=1)
    assert axis.encoder_estimates() == odrive.encode(9, "Get_Encoder_Estimates", Pos_Estimate=-2.75, Vel_Estimate=13.5)
    assert axis.heartbeat().dlc == 8 and axis.encoder_estimates().dlc == 8


def test_bad_config_is_a_clear_error():
    with pytest.raises(ValueError, match="vel_gain must be a finite number >= 0"):
        AxisConfig(vel_gain=-1)
    with pytest.raises(ValueError, match="control_mode 0 is not one of"):
        AxisConfig(control_mode=0)
    with pytest.raises(ValueError, match="node id must be 0..63"):
        OdriveAxis(64)
