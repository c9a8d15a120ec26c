"""How long a classic CAN frame occupies the bus: its bits, stuff bits included, at a bitrate.

A frame on the wire is SOF, the arbitration field, the control field, the data, a 15-bit CRC
(these are bit-stuffed: after five equal bits the sender inserts one opposite bit), then CRC
delimiter, ACK slot and delimiter, 7 bits of end of frame and 3 bits of intermission before the
next frame may start. A standard frame with 8 data bytes is 111 bits unstuffed and at most 135
with worst-case stuffing: 111-135 us at 1 Mbit/s. `stuffing="exact"` counts the stuff bits the
frame really has (its CRC included); `"worst"` takes the bound floor((stuffed_bits - 1) / 4).
"""
from __future__ import annotations

CRC15_POLY = 0x4599          # x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1
UNSTUFFED_TAIL = 1 + 2 + 7   # CRC delimiter, ACK slot + delimiter, end of frame
INTERMISSION = 3             # bus idle bits between two frames


def crc15(bits: list[int]) -> int:
    """The CAN CRC-15 of a bit sequence (SOF through data)."""
    crc = 0
    for bit in bits:
        feedback = bit ^ (crc >> 14)
        crc = (crc << 1) & 0x7FFF
        if feedback:
            crc ^= CRC15_POLY
    return crc


def _bits(value: int, width: int) -> list[int]:
    return [(value >> shift) & 1 for shift in range(width - 1, -1, -1)]


def stuffed_region(id: int, extended: bool, rtr: bool, data: bytes, dlc: int | None = None) -> list[int]:
    """The bits from SOF to the end of the CRC, before stuffing (dominant = 0)."""
    dlc = len(data) if dlc is None else dlc
    if extended:
        head = ([0] + _bits(id >> 18, 11) + [1, 1] + _bits(id & 0x3FFFF, 18) + [int(rtr)]
                + [0, 0] + _bits(dlc, 4))  # SOF, base id, SRR, IDE, id extension, RTR, r1, r0, DLC
    else:
        head = [0] + _bits(id, 11) + [int(rtr), 0, 0] + _bits(dlc, 4)  # SOF, id, RTR, IDE, r0, DLC
    body = head + ([] if rtr else [bit for byte in data for bit in _bits(byte, 8)])
    return body + _bits(crc15(body), 15)


def stuff_bit_count(bits: list[int]) -> int:
    """How many stuff bits a sender inserts into `bits`."""
    count, run, last = 0, 0, None
    for bit in bits:
        if bit == last:
            run += 1
        else:
            last, run = bit, 1
        if run == 5:
            count += 1
            last, run = 1 - bit, 1  # the stuff bit starts the next run
    return count


def frame_bits(id: int, extended: bool = False, rtr: bool = False, data: bytes = b"",
               stuffing: str = "exact", dlc: int | None = None) -> int:
    """Bits a frame occupies the bus for, intermission included (the time until the next SOF)."""
    region = stuffed_region(id, extended, rtr, data, dlc)
    if stuffing == "exact":
        stuff = stuff_bit_count(region)
    elif stuffing == "worst":
        stuff = (len(region) - 1) // 4
    elif stuffing == "none":
        stuff = 0
    else:
        raise ValueError(f"stuffing must be 'exact', 'worst' or 'none', got {stuffing!r}")
    return len(region) + stuff + UNSTUFFED_TAIL + INTERMISSION


def frame_time(frame, bitrate: float = 1_000_000, stuffing: str = "exact") -> float:
    """Seconds a `Frame` (or anything with id, extended, rtr, data) occupies a bus of `bitrate`."""
    return frame_bits(frame.id, frame.extended, frame.rtr, bytes(frame.data), stuffing) / bitrate
