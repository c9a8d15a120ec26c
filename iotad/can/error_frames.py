"""What a SocketCAN error frame says, in words: `describe_error_frame(id, data)`.

A Linux CAN socket hands its reader error frames as well as data frames (python-can asks for all
of them): the controller's report of a bus problem. The error classes are bits of the frame's id,
and some classes give details in its data bytes (linux/can/error.h):

    id bits   0x001 TX timeout     0x002 lost arbitration  0x004 controller problem (data[1])
              0x008 protocol violation (data[2], location data[3])   0x010 transceiver (data[4])
              0x020 no ACK         0x040 bus off           0x080 bus error
              0x100 controller restarted                   0x200 error counters (data[6] TX, data[7] RX)

No IOTA takes an error frame as a `canFrame`: the node host records it (iotad/host/can_port.py).
"""
from __future__ import annotations

CLASSES = (
    (0x001, "TX timeout"),
    (0x002, "lost arbitration"),
    (0x004, "controller problem"),
    (0x008, "protocol violation"),
    (0x010, "transceiver problem"),
    (0x020, "no ACK on transmission"),
    (0x040, "bus off"),
    (0x080, "bus error"),
    (0x100, "controller restarted"),
)
CONTROLLER = (  # data[1]
    (0x01, "RX buffer overflow"),
    (0x02, "TX buffer overflow"),
    (0x04, "RX warning level"),
    (0x08, "TX warning level"),
    (0x10, "RX error passive"),
    (0x20, "TX error passive"),
    (0x40, "back to error active"),
)
PROTOCOL = (  # data[2]
    (0x01, "single bit error"),
    (0x02, "frame format error"),
    (0x04, "bit stuffing error"),
    (0x08, "unable to send a dominant bit"),
    (0x10, "unable to send a recessive bit"),
    (0x20, "bus overload"),
    (0x40, "active error announcement"),
    (0x80, "error while transmitting"),
)
COUNTERS = 0x200


def _named(bits: int, names: tuple) -> list[str]:
    return [name for bit, name in names if bits & bit]


def describe_error_frame(arbitration_id: int, data: bytes | bytearray | list[int]) -> str:
    """One line naming an error frame's classes and their details, e.g.
    "bus off; controller problem (TX error passive); error counters TX 136, RX 0"."""
    data = bytes(data) + bytes(max(0, 8 - len(data)))
    parts = []
    for bit, name in CLASSES:
        if not arbitration_id & bit:
            continue
        details = []
        if bit == 0x004:
            details = _named(data[1], CONTROLLER)
        elif bit == 0x008:
            details = _named(data[2], PROTOCOL)
        elif bit == 0x002 and data[0]:
            details = [f"in bit {data[0]}"]
        parts.append(f"{name} ({', '.join(details)})" if details else name)
    if arbitration_id & COUNTERS:
        parts.append(f"error counters TX {data[6]}, RX {data[7]}")
    return "; ".join(parts) or f"unspecified error (class bits 0x{arbitration_id:X})"
