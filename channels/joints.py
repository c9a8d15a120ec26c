"""Joint messages for the robot stack: setpoints to motor nodes and states back from them.

Two shapes of each, because both are natural: a per-joint struct (one message per joint, as a
CAN motor node sees it) and a whole-arm struct of fixed-length arrays (one message per control
tick, as the MDL interpreter produces it). Positions are radians (or metres for a prismatic
joint), velocities per second, efforts newton-metres; `stamp` is seconds on the system's clock.
"""
from __future__ import annotations

from iotad.kernel.types import Array, Float, Int, StructType, Struct

# One joint: what a motor controller needs (ODrive Set_Input_Pos carries exactly these three).
JOINT_SETPOINT = Struct("jointSetpoint", joint=Int(0, None), position=Float, velocity_ff=Float, torque_ff=Float)

# One joint's measured state.
JOINT_STATE = Struct("jointState", joint=Int(0, None), position=Float, velocity=Float, effort=Float,
                     stamp=Float(0, None))

DEFAULT_JOINTS = 6  # the xArm6 of sim/; other arms call the factories with their own count

_arrays: dict[tuple[str, int], StructType] = {}


def joint_setpoints(joints: int = DEFAULT_JOINTS) -> StructType:
    """All joints' setpoints in one message: `jointSetpoints6` for six joints. Cached, so that
    two IOTAs asking for the same count share one type (bindings compare types)."""
    key = ("jointSetpoints", joints)
    if key not in _arrays:
        _arrays[key] = Struct(f"jointSetpoints{joints}", position=Array(Float, joints),
                              velocity_ff=Array(Float, joints), torque_ff=Array(Float, joints))
    return _arrays[key]


def joint_states(joints: int = DEFAULT_JOINTS) -> StructType:
    """All joints' measured states in one message, with one time stamp: `jointStates6`."""
    key = ("jointStates", joints)
    if key not in _arrays:
        _arrays[key] = Struct(f"jointStates{joints}", position=Array(Float, joints),
                              velocity=Array(Float, joints), effort=Array(Float, joints),
                              stamp=Float(0, None))
    return _arrays[key]


JOINT_SETPOINTS = joint_setpoints()
JOINT_STATES = joint_states()
