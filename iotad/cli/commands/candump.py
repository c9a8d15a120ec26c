"""`iotad candump`: CAN frames decoded by name (ODrive CAN Simple, and CANopen for CiA 402 drives), like
can-utils' candump, from a recording or from a live bus.

A recording holds every frame as a trace event of the node that sent it (`can_tx`) and of each
node that received it (`can_rx`; with `iotad run --virtual`, the modelled bus's `tx[i]`/`rx[i]` too).
By default each frame is printed once, as it went on the bus: the sender's `can_tx`. Lines are
`NODE  TIME  DIRECTION  ID  [DLC]  DATA  MESSAGE node=N SIGNALS...` (iotad/can/dump.py).
"""
from __future__ import annotations

import argparse
import sys

from iotad.can.canopen_ids import canopen_nodes

ORDER = 37

EPILOG = """\
examples:
  iotad candump arm.mcap                                every frame put on the bus, by its sender
  iotad candump arm.mcap --rx --node odrives            what the simulated ODrives received
  iotad candump arm.mcap --log                          what the bus itself carried (its log topic)
  iotad candump arm.mcap --message Heartbeat --axis 3   axis 3's heartbeats
  iotad candump arm.mcap --start 2 --end 2.1 --count 50
  iotad candump --live examples/arm_can.toml            a running system's bus ([[can]], python-can)
  python -m iotad.can.tiers run -- .venv/bin/iotad candump --live --count 20    the tier's bus
  iotad candump --live --interface socketcan --channel can0

CANopen frames (NMT, SYNC, EMCY by name, SDO, PDOs by mapping, heartbeats) are decoded for the
CiA 402 node ids that a recording's or system file's motor node (joints with protocol = "cia402")
or simulated drives name, or that --canopen gives; the PDO mappings are the EDS's, changed by the
SDO writes seen on the bus.

Times are the recording's seconds (the receive time stamp on a live bus). Frames CAN Simple does
not know end in 'unknown', known ones of the wrong shape in 'malformed: ...'. On a live bus, error
frames show as 'ERROR  bus off; ...' in words, whatever the filters. See docs/can.md."""

ACTIONS = {"tx": ("can_tx",), "rx": ("can_rx",), "all": ("can_tx", "can_rx", "tx", "rx"),
           "log": ("frames",)}  # the bus's own log: the modelled bus's, or a real bus's logger node


def register(sub: argparse._SubParsersAction) -> None:
    from iotad.cli import nonnegative_float, positive_int

    parser = sub.add_parser("candump", help="print CAN frames decoded by name, from a recording or a live bus",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("source", metavar="RECORDING | SYSTEM.toml", nargs="?",
                        help="an MCAP recording; with --live, a system file whose [[can]] bus to open")
    parser.add_argument("--live", action="store_true",
                        help="print a live bus: the system file's [[can]] bus, --interface/--channel, or the "
                             "tier's (IOTAD_CAN_INTERFACE, IOTAD_CAN_CHANNEL)")
    parser.add_argument("--bus", metavar="NAME", help="which [[can]] bus of the system file (default: its only one)")
    parser.add_argument("--interface", help="python-can interface for --live: socketcan | udp_multicast | virtual")
    parser.add_argument("--channel", help="python-can channel for --live: vcan0, can0, a multicast group")
    direction = parser.add_mutually_exclusive_group()
    direction.add_argument("--rx", action="store_const", dest="direction", const="rx",
                           help="recording: the frames nodes received (can_rx) instead of those sent")
    direction.add_argument("--all", action="store_const", dest="direction", const="all",
                           help="recording: every frame event, sent and received (and the modelled bus's)")
    direction.add_argument("--log", action="store_const", dest="direction", const="log",
                           help="recording: the bus's own log (iota/SYSTEM/BUS/frames), every frame it carried "
                                "in its order: the modelled bus's, or in real time the bus logger's")
    parser.set_defaults(direction="tx")
    parser.add_argument("--node", action="append", metavar="NAME", help="only this node's events (repeatable)")
    parser.add_argument("--message", action="append", metavar="NAME",
                        help="only this CAN Simple message, e.g. Heartbeat, Set_Input_Pos (repeatable)")
    parser.add_argument("--axis", type=int, action="append", metavar="N", help="only frames of ODrive node id N")
    parser.add_argument("--start", type=nonnegative_float, metavar="T", help="recording: from time T (s)")
    parser.add_argument("--end", type=nonnegative_float, metavar="T", help="recording: up to time T (s)")
    parser.add_argument("--canopen", metavar="N,N...", type=_node_list, default=None,
                        help="decode frames of these CiA 402 node ids (1..127) as CANopen (default: those the "
                             "recording or system file names)")
    parser.add_argument("--eds", metavar="FILE", help="the CiA 402 drives' EDS (default: iotad's simulated drive's)")
    parser.add_argument("--count", type=positive_int, metavar="N", help="stop after N frames")
    parser.add_argument("--timeout", type=nonnegative_float, default=0.0, metavar="S",
                        help="--live: stop after S quiet seconds (default: never)")
    parser.set_defaults(func=run)


def _node_list(text: str) -> frozenset:
    try:
        nodes = frozenset(int(part, 0) for part in text.split(",") if part.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected node ids like 1,2,3, got {text!r}") from None
    if not nodes or not all(1 <= n <= 127 for n in nodes):
        raise argparse.ArgumentTypeError(f"CANopen node ids are 1..127, got {text!r}")
    return nodes


def _tracker(args: argparse.Namespace, named: frozenset):
    from iotad.can.canopen import DRIVE_EDS, PdoTracker
    from iotad.cli import CliError

    nodes = args.canopen if args.canopen is not None else named
    if not nodes:
        return None
    try:
        return PdoTracker(nodes, args.eds or DRIVE_EDS)
    except ValueError as exc:
        raise CliError(str(exc)) from None


class _Filter:
    def __init__(self, args: argparse.Namespace):
        from iotad.can import odrive

        unknown = sorted(set(args.message or ()) - set(odrive.MESSAGES))
        if unknown:
            from iotad.cli import CliError

            raise CliError(f"--message {', '.join(unknown)}: not a CAN Simple message; one of "
                           f"{', '.join(sorted(odrive.MESSAGES))}")
        self.messages, self.axes = set(args.message or ()), set(args.axis or ())

    def __call__(self, frame) -> bool:
        from iotad.can import odrive
        from iotad.can.frame import Frame

        if not isinstance(frame, Frame):  # a recorded value that is no frame: shown unless filtered
            return not (self.axes or self.messages)
        if self.axes and (frame.extended or frame.id >> 5 not in self.axes):
            return False
        if self.messages:
            try:
                return odrive.decode(frame).name in self.messages
            except (odrive.UnknownFrame, ValueError):
                return False
        return True


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError

    if args.start is not None and args.end is not None and args.start > args.end:
        raise CliError(f"--start {args.start:g} is after --end {args.end:g}: no frame can lie between them")
    for axis in args.axis or ():
        if not 0 <= axis <= 0x3F:  # CAN Simple: node id = arbitration id >> 5 of an 11-bit id
            raise CliError(f"--axis {axis}: an ODrive node id is 0 to 63")
    if args.live:
        if args.start is not None or args.end is not None or args.direction != "tx" or args.node:
            raise CliError("--start, --end, --rx, --all and --node read a recording; a live bus has none of them")
        return live(args, _Filter(args))
    if not args.source:
        raise CliError("give a recording (iotad candump FILE.mcap), or --live for a bus")
    if args.interface or args.channel or args.bus or args.timeout:
        raise CliError("--interface, --channel, --bus and --timeout are for --live")
    return recorded(args, _Filter(args))


def frame_events(recording, direction: str = "tx", nodes=None, start=None, end=None):
    """(t, node, action, index, Frame) of the recording's frame events, in time order; an event
    whose value is no CAN frame (a can_rx input id 5000 with extended false: the type takes it,
    the node reports it malformed) keeps its value, which `format_frame` shows as such."""
    from iotad.can.frame import Frame, FrameError

    actions = ACTIONS[direction]
    found = []
    unit = recording.time_unit  # events count spec units; frames are shown, and picked, in seconds
    for order, event in enumerate(recording.trace()):
        if event.get("action") not in actions or event.get("kind") not in ("input", "output"):
            continue
        node = event.get("node") or event.get("iota", "")
        if nodes and node not in nodes:
            continue
        t = event.get("t")
        if not isinstance(t, (int, float)):
            continue
        t = t * unit
        if (start is not None and t < start) or (end is not None and t > end):
            continue
        try:
            frame = Frame.from_value(event.get("value"))
        except FrameError:
            frame = event.get("value")  # shown as "not a CAN frame: why", never dropped in silence
        found.append((float(t), order, node, event["action"], event.get("index"), frame))
    found.sort(key=lambda item: (item[0], item[1]))
    return [(t, node, action, index, frame) for t, _, node, action, index, frame in found]


def recorded(args: argparse.Namespace, keep: _Filter) -> int:
    from iotad.can.dump import format_frame
    from iotad.cli import CliError

    from iotad.cli.recordings import load

    recording = load(args.source)
    canopen = _tracker(args, canopen_nodes(spec.get("params") for spec in recording.specs.values()
                                           if isinstance(spec, dict)))
    events = frame_events(recording, args.direction, set(args.node or ()), args.start, args.end)
    if not events:
        nodes = f" of node(s) {', '.join(args.node)}" if args.node else ""
        if args.start is not None or args.end is not None:
            span = f"between {args.start or 0:g} s and {'the end' if args.end is None else f'{args.end:g} s'}"
            everything = frame_events(recording, args.direction, set(args.node or ()))
            if everything:
                raise CliError(f"{args.source}: no CAN frame events{nodes} {span} (its frames span "
                               f"{everything[0][0]:g} to {everything[-1][0]:g} s)")
        raise CliError(f"{args.source}: no CAN frame events{nodes} (nodes on a [[can]] bus record can_tx and can_rx)")
    width = max(len(node) for _, node, *_ in events)
    shown = 0
    out = sys.stdout
    for t, node, action, index, frame in events:
        if not keep(frame):
            continue
        direction = action if index is None else f"{action}[{index}]"
        out.write(f"{node:<{width}}  {format_frame(t, frame, direction, canopen).lstrip()}\n")
        shown += 1
        if args.count and shown >= args.count:
            break
    out.flush()
    return 0


def live(args: argparse.Namespace, keep: _Filter) -> int:
    from iotad.can.bus import BusUnavailable
    from iotad.can.dump import live_lines
    from iotad.cli import CliError
    from iotad.cli.can_bus import live_bus

    try:
        bus = live_bus(args)
    except BusUnavailable as exc:
        raise CliError(str(exc)) from None
    with bus:
        print(f"candump: {bus.describe()}", file=sys.stderr, flush=True)
        canopen = _tracker(args, getattr(args, "named_canopen", frozenset()))
        for line in live_lines(bus, args.timeout or None, args.count, keep, canopen):
            print(line, flush=True)
    return 0
