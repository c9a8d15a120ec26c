"""`OdriveLink`, the CAN motor node's side of one ODrive axis (CAN Simple, firmware 0.6): arming frames, setpoint frames, the heartbeat and the other axis messages.

The axis's state is its cyclic Heartbeat (axis state, axis error): armed when it reports
CLOSED_LOOP_CONTROL after the node asked for it, disarmed when it leaves it. Frames come from
`iotad.can.odrive`; docs/can_motor.md describes the sequence.
"""
from __future__ import annotations

import math
import struct
from typing import Any

from iotad.can.frame import Frame
from iotad.can.odrive import (AXIS_STATE, CONTROL_MODE, INPUT_MODE, MESSAGES, EncodeError, MalformedFrame,
                              UnknownFrame, decode, encode, frame_id, request, undefined_values)

from .drive_link import FAULT, UNARMED, DriveLink
from .joint_map import JointConfig, JointMapError

CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]
FF_MAX = 32.767  # Set_Input_Pos carries Vel_FF and Torque_FF as int16 x 0.001
_ESTIMATES = struct.Struct("<ff").unpack  # Pos_Estimate, Vel_Estimate (turns, turns/s), float32


class OdriveLink(DriveLink):
    """One ODrive axis at `joint.node_id` (0..63): command ids node_id << 5 .. + 31."""

    family = "odrive"
    feeds_watchdog = True  # the firmware's watchdog is fed by commands: keep-alive and arm-hold

    def __init__(self, node, index: int):
        super().__init__(node, index)
        self.idle_sent = False  # IDLE went out for closed loop the node did not command (UNCOMMANDED_STATE)
        self._estimates_id = frame_id(self.joint.node_id, "Get_Encoder_Estimates")
        try:  # a limit or gain no float32 holds (1e39) is refused when the node is built
            _arming_frames(self.joint)
        except EncodeError as exc:
            raise JointMapError(f"joint {self.joint.name}: {exc} (in the frames that arm its axis)") from None

    @staticmethod
    def node_id_of(frame_id: int) -> int:
        return frame_id >> 5  # CAN Simple: node_id << 5 | cmd_id

    def frame_ids(self):
        return range(self.joint.node_id << 5, (self.joint.node_id << 5) + 32)

    # ------------------------------------------------------------------ frames to the axis
    def arming_frames(self) -> list[Frame]:
        joint, axis = self.joint, self.axis
        frames = _arming_frames(joint)
        # The hold command before closed loop: the firmware keeps the input velocity and torque it
        # was last given across IDLE (only a position input is reset to where the axis is), so an
        # axis re-armed after a watchdog trip, an estop reset or a restart would resume its last
        # speed or torque until our first setpoint came. A position axis gets one only where it
        # was measured: to an axis still armed (a restarted node) any other position is a move.
        if joint.mode != "position" or axis.has_position:
            frames.insert(-1, setpoint_frame(joint, axis.command, 0.0, 0.0))
        return frames

    def setpoint_frames(self, command: float, velocity_ff: float, torque_ff: float) -> tuple[Frame, ...]:
        return (setpoint_frame(self.joint, command, velocity_ff, torque_ff),)

    def stop_frames(self) -> list[Frame]:
        return [encode(self.joint.node_id, "Estop")]

    def idle_frames(self) -> list[Frame]:
        return [encode(self.joint.node_id, "Set_Axis_State", Axis_Requested_State=AXIS_STATE["IDLE"])]

    def poll_frames(self, name: str) -> list[Frame]:
        return [request(self.joint.node_id, name)]

    # ------------------------------------------------------------------ frames from the axis
    def receive(self, frame: Frame, value: Any) -> None:
        # The estimates, most of what an axis sends (one per setpoint at 500 Hz): read at once,
        # with the checks `decode` and the lines below make of one (a data frame of 8 bytes, two
        # finite numbers); anything else about it goes the long way, which says what is wrong.
        if frame.id == self._estimates_id and frame.dlc == 8 and not frame.rtr:
            position, velocity = _ESTIMATES(frame.data)
            if position - position == 0.0 and velocity - velocity == 0.0:  # neither inf nor NaN
                self._estimates(position, velocity)
                return
        node = self.node
        try:
            message = decode(frame)
        except UnknownFrame:
            node.reject_frame("UNKNOWN_COMMAND", value)
            return
        except MalformedFrame:
            node.reject_frame("WRONG_DLC", value)
            return
        if message.rtr or MESSAGES[message.name].sender == "host":
            node.reject_frame("UNEXPECTED", value)
            return
        signals = message.signals
        if not all(math.isfinite(v) for v in signals.values()) or undefined_values(signals):
            node.reject_frame("BAD_VALUE", value)  # NaN, or an Axis_State no firmware has: not believed
            return
        handler = _HANDLERS.get(message.name)
        if handler is not None:
            handler(self, signals)
        # Get_Version, TxSdo, Address, Get_Powers: valid, nothing here uses them

    def _on_heartbeat(self, signals: dict) -> None:
        axis, node = self.axis, self.node
        previous_error = axis.axis_error
        axis.axis_error = signals["Axis_Error"]
        axis.axis_state = signals["Axis_State"]
        axis.procedure_result = signals["Procedure_Result"]
        axis.trajectory_done = bool(signals["Trajectory_Done_Flag"])
        axis.heard = True
        axis.beat = True
        events = []
        if axis.lost:
            axis.lost = False
            events.append("FOUND")
        closed = axis.axis_state == CLOSED_LOOP
        # an axis error is the firmware saying it is not well, closed loop or not: not enabled
        events += node.drive_enabled(self.index, closed and not axis.axis_error)
        if axis.axis_error and axis.axis_error != previous_error:
            events.append("AXIS_ERROR")
        if closed and (axis.axis_error or axis.phase in (UNARMED, FAULT)) and not self.idle_sent:
            # closed loop that the node did not command (or with an error): IDLE, once per episode
            node.send(self.idle_frames())
            self.idle_sent = True
            events.append("UNCOMMANDED_STATE")
        elif not closed:
            self.idle_sent = False
        for event in events or ["HEARTBEAT"]:
            node.report(self.index, event)

    def _on_encoder_estimates(self, signals: dict) -> None:
        self._estimates(signals["Pos_Estimate"], signals["Vel_Estimate"])

    def _estimates(self, position: float, velocity: float) -> None:
        joint, axis = self.joint, self.axis
        axis.position = joint.position(position)
        axis.velocity = joint.velocity(velocity)
        axis.has_position = True

    def _on_error(self, signals: dict) -> None:
        axis = self.axis
        active, reason = signals["Active_Errors"], signals["Disarm_Reason"]
        if (active, reason) != (axis.active_errors, axis.disarm_reason):
            axis.active_errors, axis.disarm_reason = active, reason
            self.node.report(self.index, "ERRORS")

    def _on_torques(self, signals: dict) -> None:
        axis = self.axis
        axis.torque_estimate = signals["Torque_Estimate"]
        axis.effort = self.joint.torque(axis.torque_estimate)

    def _on_iq(self, signals: dict) -> None:
        self.axis.iq_measured = signals["Iq_Measured"]

    def _on_temperature(self, signals: dict) -> None:
        axis = self.axis
        axis.fet_temperature, axis.motor_temperature = signals["FET_Temperature"], signals["Motor_Temperature"]

    def _on_bus(self, signals: dict) -> None:
        axis = self.axis
        axis.bus_voltage, axis.bus_current = signals["Bus_Voltage"], signals["Bus_Current"]


_HANDLERS = {"Heartbeat": OdriveLink._on_heartbeat, "Get_Encoder_Estimates": OdriveLink._on_encoder_estimates,
             "Get_Error": OdriveLink._on_error, "Get_Torques": OdriveLink._on_torques, "Get_Iq": OdriveLink._on_iq,
             "Get_Temperature": OdriveLink._on_temperature, "Get_Bus_Voltage_Current": OdriveLink._on_bus}


def _saturate(value: float, limit: float) -> float:
    return value if -limit <= value <= limit else math.copysign(limit, value)


def setpoint_frame(joint: JointConfig, command: float, velocity_ff: float, torque_ff: float) -> Frame:
    """The frame that commands `command` (joint units, in the joint's mode) with feed-forward.
    Feed-forward is limited to the joint's limits and to what the frame can carry, silently."""
    node = joint.node_id
    torque_ff = _saturate(torque_ff, joint.torque_limit)
    if joint.mode == "position":
        velocity_ff = _saturate(velocity_ff, joint.velocity_limit)
        return encode(node, "Set_Input_Pos", Input_Pos=joint.turns(command),
                      Vel_FF=_saturate(joint.turns_per_second(velocity_ff), FF_MAX),
                      Torque_FF=_saturate(joint.motor_torque(torque_ff), FF_MAX))
    if joint.mode == "velocity":
        return encode(node, "Set_Input_Vel", Input_Vel=joint.turns_per_second(command),
                      Input_Torque_FF=joint.motor_torque(torque_ff))
    return encode(node, "Set_Input_Torque", Input_Torque=joint.motor_torque(command))


def _arming_frames(joint: JointConfig) -> list[Frame]:
    """Clear_Errors, the controller mode, the limits, the optional gains, then closed loop."""
    node = joint.node_id
    frames = [encode(node, "Clear_Errors", Identify=0),
              encode(node, "Set_Controller_Mode", Control_Mode=CONTROL_MODE[joint.control_mode],
                     Input_Mode=INPUT_MODE[joint.input_mode]),
              encode(node, "Set_Limits", Velocity_Limit=joint.motor_velocity_limit, Current_Limit=joint.current_limit)]
    if joint.pos_gain is not None:
        frames.append(encode(node, "Set_Pos_Gain", Pos_Gain=joint.pos_gain))
    if joint.vel_gain is not None:
        frames.append(encode(node, "Set_Vel_Gains", Vel_Gain=joint.vel_gain,
                             Vel_Integrator_Gain=joint.vel_integrator_gain))
    if joint.traj_vel_limit is not None:
        frames.append(encode(node, "Set_Traj_Vel_Limit", Traj_Vel_Limit=joint.traj_vel_limit))
    if joint.traj_accel_limit is not None:
        frames.append(encode(node, "Set_Traj_Accel_Limits", Traj_Accel_Limit=joint.traj_accel_limit,
                             Traj_Decel_Limit=joint.traj_decel_limit))
    if joint.traj_inertia is not None:
        frames.append(encode(node, "Set_Traj_Inertia", Traj_Inertia=joint.traj_inertia))
    frames.append(encode(node, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP))
    return frames
