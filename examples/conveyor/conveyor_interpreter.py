"""The MDL interpreter (nodes/mdl_interp) for the conveyor arm's seven joints: the xArm6's six and
the gripper's drive joint.

A named class in a file of its own, because `iotad check` rebuilds a node from the source text
stored in the recording: `nodes.mdl_interp:mdl_interpreter` makes a class per joint count at run
time (`MdlInterpreter7`) that the stored text of interpreter.py does not define.
"""
from nodes.mdl_interp.interpreter import interpreter_class


class ConveyorInterpreter(interpreter_class(7)):
    """Seven joints; every parameter and channel as nodes/mdl_interp's interpreter."""
