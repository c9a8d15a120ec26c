"""`iotad plot`: a PNG timeline of which requester held the motors, the acks and the violations."""
from __future__ import annotations

import argparse

ORDER = 36


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("plot", help="draw who held the motors, the acks and the violations (PNG)",
                            description=__doc__)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.png", help="image to write")
    parser.add_argument("--node", metavar="PATH", help="the scheduler node (default: the one that schedules)")
    parser.add_argument("--title", help="title of the plot")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.commands.info import load
    from iotad.recording import RecordingError

    recording = load(args.file)
    try:
        from iotad.plot import plot
    except ImportError:
        raise CliError("plotting needs matplotlib: pip install 'iotad[plot]'") from None
    if args.node and args.node not in recording.nodes():
        raise CliError(f"no node {args.node!r} in {args.file} (nodes: {', '.join(recording.nodes())})")
    try:
        path = plot(recording, args.output, args.node, args.title)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    print(f"wrote {path}")
    return 0
