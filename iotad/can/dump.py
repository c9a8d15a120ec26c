"""candump-like lines for CAN frames, with the ODrive CAN Simple message and signals by name, or the CANopen service.

    format_frame(1.25, frame, "rx")
    '    1.250000  rx  06C  [8]  00 00 C0 3F C8 00 00 00  Set_Input_Pos node=3 Input_Pos=1.5 Vel_FF=0.2 Torque_FF=0'

A remote frame shows `R` for its data; a frame CAN Simple does not know ends in `unknown`, a
known command of the wrong shape in `malformed: ...`. Given `canopen`, a `canopen.PdoTracker` of
the bus's CiA 402 node ids, the frames it claims (NMT, SYNC, heartbeats, those drives' EMCY, SDO
and PDOs) are decoded as CANopen instead: PDOs by their mapping, as the SDO writes on the bus set it. On a live bus an error frame is a line
`ERROR  bus off; ...` in words (`error_frames.py`). `python -m iotad.can.dump` prints a live bus
(the tier's bus by default: run it under `python -m iotad.can.tiers run -- ...`).
"""
from __future__ import annotations

import argparse
import sys
from typing import Callable, Iterator

from . import odrive
from .error_frames import describe_error_frame
from .frame import Frame, FrameError


def format_frame(t: float, frame, direction: str = "", canopen=None) -> str:
    """One line: time (s), direction, id in hex, [dlc], data bytes, the decoded message."""
    try:
        frame = frame if isinstance(frame, Frame) else Frame.from_value(frame)
    except FrameError as exc:
        return f"{t:12.6f}  {direction:>3}  not a CAN frame: {exc}"
    ident = f"{frame.id:08X}" if frame.extended else f"{frame.id:03X}"
    data = "R" if frame.rtr else frame.data.hex(" ").upper()
    return f"{t:12.6f}  {direction:>3}  {ident:>8}  [{frame.dlc}]  {data:<23}  {decoded(frame, canopen)}".rstrip()


def live_lines(bus, timeout: float | None = None, count: int = 0,
               keep: Callable[[Frame], bool] = lambda frame: True, canopen=None) -> Iterator[str]:
    """The lines of what a live bus (`bus.open_bus`) carries, as it comes, until `count` lines
    (0: never) or `timeout` quiet seconds (None: never). Its frames that `keep` takes, and, whatever
    `keep` says (they concern the whole bus), what no IOTA can take: an error frame in words
    (`ERROR  bus off; ...`), a CAN FD frame."""
    shown = 0
    while not count or shown < count:
        message = bus.recv(timeout)
        if message is None:
            return
        t = message.timestamp
        if message.is_error_frame:
            yield f"{t:12.6f}  {'rx':>3}  {'ERROR':>8}  {describe_error_frame(message.arbitration_id, message.data)}"
        else:
            try:
                frame = Frame.from_can_message(message)
            except FrameError as exc:
                yield f"{t:12.6f}  {'rx':>3}  {'':>8}  not a classic frame: {exc}"
            else:
                if not keep(frame):
                    continue
                yield format_frame(t, frame, "rx", canopen)
        shown += 1


def decoded(frame: Frame, canopen=None) -> str:
    """The ODrive message a frame carries, in words; `unknown` or `malformed: why` otherwise. With
    `canopen` (a PdoTracker), the CANopen service of a frame it claims."""
    if canopen is not None and canopen.claims(frame):
        try:
            return canopen.describe(frame)
        except FrameError as exc:
            return f"malformed: {exc}"
    if frame.extended:
        return "unknown"  # CAN Simple uses 11-bit ids: another protocol shares the bus
    try:
        return odrive.describe(odrive.decode(frame))
    except odrive.UnknownFrame:
        return "unknown"
    except FrameError as exc:
        return f"malformed: {exc}"


def frame_fields(t: float, frame, direction: str) -> dict:
    """A frame as a record for recordings: time, id, extended, rtr, dlc, data (list of bytes),
    direction, and the ODrive message name (None where CAN Simple does not know the frame)."""
    frame = frame if isinstance(frame, Frame) else Frame.from_value(frame)
    try:
        name = None if frame.extended else odrive.decode(frame).name
    except FrameError:
        name = None
    return {"t": t, "id": frame.id, "extended": frame.extended, "rtr": frame.rtr, "dlc": frame.dlc,
            "data": list(frame.data), "direction": direction, "name": name}


def format_event(event: dict) -> str | None:
    """The line of a trace event carrying a CAN frame (a bus's tx/rx, a node's can_tx/can_rx);
    None for other events. The direction is the event's action and index: `rx[2]`, `can_tx`."""
    value = event.get("value")
    if not isinstance(value, dict) or "dlc" not in value or "data" not in value:
        return None
    action = event.get("action", "")
    index = event.get("index")
    direction = action if index is None else f"{action}[{index}]"
    return f"{event.get('iota', '')}  " + format_frame(float(event.get("t", 0.0)), value, direction).lstrip()


def main(argv: list[str] | None = None) -> int:
    from .bus import BusUnavailable, open_bus, open_env_bus

    parser = argparse.ArgumentParser(prog="python -m iotad.can.dump",
                                     description="Print a live CAN bus's frames, decoded as ODrive CAN Simple.")
    parser.add_argument("--interface", help="socketcan | udp_multicast | virtual (default: the tier's, "
                                            "from IOTAD_CAN_INTERFACE)")
    parser.add_argument("--channel", help="vcan0, can0, a multicast group... (default: the interface's)")
    parser.add_argument("--count", type=int, default=0, help="stop after this many frames (0: never)")
    parser.add_argument("--timeout", type=float, default=0.0, help="stop after this many quiet seconds (0: never)")
    args = parser.parse_args(argv)
    try:
        bus = open_bus(args.interface, args.channel) if args.interface else open_env_bus()
    except BusUnavailable as exc:
        print(f"iotad.can.dump: {exc}", file=sys.stderr)
        return 2
    try:
        with bus:
            for line in live_lines(bus, args.timeout or None, args.count):
                print(line, flush=True)
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
