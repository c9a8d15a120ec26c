"""iotad: a runtime of Input-Output Timed Automata for robots that share motors."""
from .api import Input, Internal, Iota, Output, Param
from .clock import RealClock, VirtualClock
from .compose import Composite
from .engine import Engine
from .model import IotaSpec, SpecError
from .policy import Eager, Random
from .script import run_script
from .types import Array, Bool, Enum, Float, Int, Struct

__version__ = "0.1.0"

__all__ = ["Array", "Bool", "Composite", "Eager", "Engine", "Enum", "Float", "Input", "Int", "Internal",
           "Iota", "IotaSpec", "Output", "Param", "Random", "RealClock", "SpecError", "Struct",
           "VirtualClock", "run_script", "__version__"]
