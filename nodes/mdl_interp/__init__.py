"""The MDL interpreter: motion programs (channels/mdl.py) to per-joint setpoints at the control rate.

`MdlInterpreter` is the IOTA for six joints (the xArm6); `mdl_interpreter(name, joints=[...])`
makes one for any joint count, and is what a system file's node names
(`ref = "nodes.mdl_interp:mdl_interpreter"`). docs/mdl.md describes channels, parameters and
the program format.
"""
from .interpreter import MdlInterpreter, interpreter_class, mdl_interpreter

__all__ = ["MdlInterpreter", "interpreter_class", "mdl_interpreter"]
