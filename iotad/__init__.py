"""iotad: a runtime of Input-Output Timed Automata for robots that share motors.

The package is layered; each layer imports only the layers before it (tests/test_layering.py):

    iotad.kernel     the IOTA model, engine, clocks, policies, composition, Python API
    iotad.esprit     the ESPRIT specification language, compiled onto the kernel
    iotad.can        CAN frames, buses (real and modelled) and the ODrive CAN Simple protocol
    iotad.ros2       ROS 2 interop: rmw_zenoh's wire format, channel-to-message mappings, the bridge
    iotad.machine    a machine of a system over hosts: certificates, its agent's secret, its clock offset
    iotad.node_host  the node host: one IOTA as one process on zenoh (and its CAN bus): wire, transport
    iotad.launcher   system files, access control, several hosts, the run of one host (`iotad run`)
    iotad.recording  MCAP recordings: recorder, reading, replay, conformance checks, export, plots
    iotad.virtual    a system run in one process in virtual time (`run_virtual`)
    iotad.sweep      many virtual runs over parameters and seeds, locally or on Ray
    iotad.scaffold   `iotad new`: a working robot's files from a few choices
    iotad.cli        the `iotad` command line, one module per command: parses, calls, prints

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
           "VirtualClock", "open_recording", "run_script", "__version__"]


def __getattr__(name: str):
    # `iotad.open_recording` on first use: reading recordings loads MCAP and zenoh's wire module,
    # which a node (or `import iotad` alone) does not need
    if name == "open_recording":
        from .recording.open_recording import open_recording
        return open_recording
    raise AttributeError(f"module 'iotad' has no attribute {name!r}")
