"""The CAN-bus motor node: joint setpoints to ODrive CAN Simple frames, CAN feedback to joint states.

`CanMotor` is the IOTA (system files: python = "nodes.can_motor:CanMotor"); `joint_map` parses
and converts its joint map. docs/can_motor.md describes both.
"""
from .joint_map import JointConfig, JointMapError, parse_joints
from .node import CanMotor

__all__ = ["CanMotor", "JointConfig", "JointMapError", "parse_joints"]
