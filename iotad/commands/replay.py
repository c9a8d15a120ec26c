"""`iotad replay`: re-run a recorded node in virtual time and compare, or republish a recording live."""
from __future__ import annotations

import argparse

ORDER = 33


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "replay", help="re-run a node against its recorded inputs and compare; or republish (--live)",
        description="With --node: rebuild PATH from the spec stored in the recording, feed it its recorded "
                    "inputs in virtual time, and compare its outputs with the recorded ones (values equal, "
                    "times within --tolerance); print the first divergence with the events around it; "
                    "exit 0 only when they agree. With --live: republish every message on its zenoh key at "
                    "the recorded pace.",
        epilog="examples: iotad replay run.mcap --node scheduler; iotad replay run.mcap --live --rate 2 --loop")
    parser.add_argument("file", metavar="FILE", help="an MCAP recording")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--node", metavar="PATH", help="the node to re-run and compare")
    what.add_argument("--live", action="store_true", help="republish the recording on zenoh")
    parser.add_argument("--tolerance", type=float, default=None, metavar="T",
                        help="allowed time difference, spec time units (default: exact for virtual-time "
                             "recordings, 10 ms for real ones)")
    parser.add_argument("--internal", action="store_true", help="compare internal events too, not only outputs")
    parser.add_argument("--rate", type=float, default=1.0, metavar="R", help="--live: speed factor (default 1)")
    parser.add_argument("--start", type=float, default=0.0, metavar="S", help="--live: skip the first S seconds")
    parser.add_argument("--loop", action="store_true", help="--live: start again at the end (Ctrl-C stops)")
    parser.add_argument("--connect", action="append", default=[], metavar="EP", help="--live: zenoh endpoint")
    parser.add_argument("--listen", action="append", default=None, metavar="EP",
                        help="--live: zenoh endpoint to listen on (default tcp/127.0.0.1:0)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.commands.info import load
    from iotad.recording import RecordingError
    from iotad.replay import default_tolerance, replay_node

    recording = load(args.file)
    if args.live:
        return live(args, recording)
    tolerance = default_tolerance(recording) if args.tolerance is None else args.tolerance
    kinds = ("output", "internal") if args.internal else ("output",)
    try:
        result = replay_node(recording, args.node, tolerance, kinds)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    print("\n".join(result.lines()))
    return 0 if result.ok else 1


def live(args: argparse.Namespace, recording) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from iotad.cli import CliError
    from iotad.replay import republish
    from iotad.transport import DEFAULT_LISTEN, open_session

    if args.rate <= 0:
        raise CliError("--rate must be > 0")
    session = open_session(args.listen or DEFAULT_LISTEN, args.connect)
    try:
        with Progress(TextColumn("replaying"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                      TimeRemainingColumn()) as progress:
            task = progress.add_task("replay", total=None)

            def show(done: int, total: int) -> None:
                progress.update(task, completed=done, total=total)

            sent = republish(recording, session, rate=args.rate, start=args.start, loop=args.loop, progress=show)
        print(f"published {sent} messages")
    finally:
        session.close()
    return 0
