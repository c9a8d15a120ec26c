"""Message types of the CAN motor node: a per-joint status report and a report of a rejected CAN frame.

`jointStatus` is what `nodes/can_motor` says about one joint's motor controller: its axis as the
last Heartbeat and Get_Error showed it, whether the node has armed it, whether its heartbeat is
lost, and why this report was sent (`event`). Routine reports (`HEARTBEAT`) echo every heartbeat;
the other events are the node's violation-like records (a lost controller, an arming time-out, a
clamped or rejected setpoint...). Telemetry fields are in the controller's units (motor side:
Nm, A, deg C, V), 0.0 until the controller has sent them.

Enum members are distinct across these enums, so that an ESPRIT spec can declare all of them
(ESPRIT enum members are global names).
"""
from __future__ import annotations

from iotad.kernel.types import Bool, Enum, Float, Int, Struct

from .can import CAN_FRAME

U32 = Int(0, 0xFFFFFFFF)
U8 = Int(0, 255)

# Where the node stands with one axis.
#   UNARMED  not armed; it will send the arming sequence (now, or after a retry delay)
#   ARMING   arming sequence sent; waiting for a Heartbeat that shows CLOSED_LOOP_CONTROL
#   ARMED    closed loop: setpoints go out
#   FAULT    the axis left closed loop on its own; it waits for a reset (estop = false)
#   ESTOPPED Estop sent; it waits for a reset (estop = false)
MOTOR_PHASE = Enum("motorPhase", "UNARMED", "ARMING", "ARMED", "FAULT", "ESTOPPED")

# Why a jointStatus report was sent.
JOINT_EVENT = Enum("jointEvent",
                   "HEARTBEAT",          # a routine heartbeat, nothing changed
                   "ARM_SENT",           # the arming sequence went out
                   "ARM_DONE",           # the heartbeat shows closed loop: armed
                   "ARM_TIMEOUT",        # no closed loop within arm_timeout: it will retry
                   "DISARMED",           # an armed axis left closed loop on its own
                   "LOST",               # no heartbeat for lost_after heartbeat periods
                   "FOUND",              # a heartbeat again after LOST
                   "AXIS_ERROR",         # the heartbeat's axis error changed to a non-zero value
                   "ERRORS",             # Get_Error's active errors or disarm reason changed
                   "SETPOINT_CLAMPED",   # a setpoint outside the limits, clamped (out_of_range = clamp)
                   "SETPOINT_REJECTED",  # a setpoint outside the limits (or not finite), not sent
                   "ESTOP",              # Estop sent to the axis
                   "RESET",              # estop = false: a FAULT or ESTOPPED axis will re-arm
                   "EMCY",               # CiA 402: the drive sent an emergency message (axis_error: its code)
                   "SDO_ABORT",          # CiA 402: the drive refused a configuration write (disarm_reason: the code)
                   "BOOT_UP",            # CiA 402: the drive (re)booted; it is configured again
                   "LINK_LOST",          # no setpoints for link_timeout: the axis was commanded IDLE
                   "LINK_FOUND",         # setpoints again after LINK_LOST
                   "NMT_PRE_OPERATIONAL",  # CiA 402: its heartbeat says PRE-OPERATIONAL while armed or arming
                   "NMT_STOPPED",        # CiA 402: its heartbeat says STOPPED while armed or arming
                   "TPDO_TIMEOUT",       # CiA 402: no statusword for tpdo_timeout SYNCs: LOST
                   "UNCOMMANDED_STATE",  # closed loop (ODrive) or OPERATION ENABLED (CiA 402, held in FAULT),
                                         # or an ODrive axis error, that the node did not command: stopped again
                   "REARM_LIMIT",        # auto_rearm gave up: rearm_limit re-arms in a row; FAULT until a reset
                   "SCALE_MISMATCH")     # CiA 402: the drive's units contradict the joint table's (disarm_reason:
                                         # the object, requested: the table's value, applied: the drive's); FAULT

JOINT_STATUS = Struct(
    "jointStatus",
    joint=Int(0, None), node_id=Int(0, 127), event=JOINT_EVENT, phase=MOTOR_PHASE, lost=Bool,
    # Heartbeat
    axis_state=U8, axis_error=U32, procedure_result=U8, trajectory_done=Bool,
    # CiA 402: the last EMCY's error register (its code is axis_error)
    error_register=U8,
    # Get_Error
    active_errors=U32, disarm_reason=U32,
    # SETPOINT_*: the joint-unit value asked for and the one the axis now follows (0.0 otherwise)
    requested=Float, applied=Float,
    # Get_Torques, Get_Iq, Get_Temperature, Get_Bus_Voltage_Current (when polled or cyclic)
    torque_estimate=Float, iq_measured=Float, fet_temperature=Float, motor_temperature=Float,
    bus_voltage=Float, bus_current=Float)

# Why a received frame was recorded and ignored.
BAD_FRAME_REASON = Enum("badFrameReason",
                        "MALFORMED",        # not a valid classic CAN frame (e.g. RTR with data)
                        "EXTENDED_ID",      # a 29-bit id: CAN Simple uses 11-bit ids
                        "UNKNOWN_NODE",     # a node id that is not in the joint map
                        "UNKNOWN_COMMAND",  # a command id CAN Simple does not have
                        "WRONG_DLC",        # a CAN Simple message with the wrong length
                        "UNEXPECTED",       # a host-side command or a remote request (another master?)
                        "BAD_VALUE")        # a float signal that is not finite

BAD_FRAME = Struct("badFrame", reason=BAD_FRAME_REASON, frame=CAN_FRAME)

__all__ = ["BAD_FRAME", "BAD_FRAME_REASON", "JOINT_EVENT", "JOINT_STATUS", "MOTOR_PHASE"]
