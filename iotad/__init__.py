"""iotad: a runtime of Input-Output Timed Automata for robots that share motors.

The package is layered; each layer imports only the layers before it (tests/test_layering.py):

    iotad.kernel     the IOTA model, engine, clocks, policies, composition, Python API
    iotad.esprit     the ESPRIT specification language, compiled onto the kernel
    iotad.can        CAN frames, buses (real and modelled) and the ODrive CAN Simple protocol
    iotad.ros2       ROS 2 interop: rmw_zenoh's wire format, channel-to-message mappings, the bridge
    iotad.host       one IOTA as one process on zenoh (and its CAN bus): wire, transport, node host
    iotad.launcher   system files, process supervision, the status view (`iotad run`)
    iotad.recording  MCAP recordings: recorder, reading, replay, conformance checks, export, plots
    iotad.cli        the `iotad` command line, one module per command

The names below are the public Python API (README.md).
"""
from .kernel.api import Input, Internal, Iota, Output, Param
from .kernel.clock import RealClock, VirtualClock
from .kernel.compose import Composite
from .kernel.engine import Engine
from .kernel.model import IotaSpec, SpecError
from .kernel.policy import Eager, Latest, Random
from .kernel.input_script import run_script
from .kernel.types import Array, Bool, Enum, Float, Int, Struct

__version__ = "0.1.0"

__all__ = ["Array", "Bool", "Composite", "Eager", "Engine", "Enum", "Float", "Input", "Int", "Internal",
           "Iota", "IotaSpec", "Latest", "Output", "Param", "Random", "RealClock", "SpecError", "Struct",
           "VirtualClock", "run_script", "__version__"]
