"""CAN buses and the ODrive CAN Simple protocol; imports only iotad.kernel.

Modules, each with one job:
- `frame`: `Frame`, one CAN frame, and `CAN_FRAME`, the channel type that carries it.
- `odrive`: ODrive CAN Simple (firmware 0.6.10) encode/decode, byte for byte as its DBC.
- `bus`: `open_bus`, a python-can bus by interface name for real time.
- `virtual_bus`: `CanBus`, the in-process bus of virtual time (an IOTA).
- `tiers`: the best CAN bus this host can give a test (vcan, user-mode Linux, udp_multicast).
- `dump`: candump-like lines with ODrive names.
"""
from .frame import CAN_FRAME, Frame, FrameError

__all__ = ["CAN_FRAME", "Frame", "FrameError"]
