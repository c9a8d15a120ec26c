"""The CAN frame message type: one classic CAN frame on an IOTA channel (`canFrame`).

Defined with the CAN layer (`iotad.can.frame`, where `Frame.to_value`/`from_value` convert it) and
re-exported here so that channels/ names every message type. Data is zero-padded to 8 bytes;
`dlc` says how many are valid. Every node on a bus has `can_tx = Output(CAN_FRAME, switching=0)`
and `can_rx = Input(CAN_FRAME, switching=0)`.
"""
from iotad.can.frame import CAN_FRAME

__all__ = ["CAN_FRAME"]
