"""`iotad replay`: re-run a recorded node in virtual time and compare, or republish a recording live."""
from __future__ import annotations

import argparse

from iotad.cli import endpoint, nonnegative_float, positive_float

ORDER = 32

EPILOG = """\
examples:
  iotad replay recordings/fig2.mcap --node scheduler              re-run and compare its outputs
  iotad replay recordings/fig2.mcap --node scheduler --internal   internal events too
  iotad replay recordings/buggy-demo.mcap --node body --free      fire at exact times, not the recorded ones
  iotad replay recordings/fig2.mcap --live --rate 2               republish at twice the pace
  iotad replay recordings/fig2.mcap --live --loop --connect tcp/127.0.0.1:7447

--tolerance is in spec time units; --rate is a speed factor; --start is seconds into the
recording. --live shows a progress bar; watch it with 'iotad echo' or Foxglove. Into a running
system's hub, --live publishes as a tool: access control (on by default in 'iotad run') drops
what [system.debug] allow_pub does not list, without telling the sender (docs/access-control.md).
See also: 'iotad check FILE' (conformance to the specs), 'iotad info FILE'."""


RATE_MIN, RATE_MAX = 1e-6, 1e6  # --rate: a millionth of real time up to a million times it


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "replay", help="re-run a node against its recorded inputs and compare; or republish (--live)",
        description="With --node: rebuild PATH from the spec stored in the recording, feed it its recorded "
                    "inputs in virtual time, and compare its outputs with the recorded ones (values equal, "
                    "times within --tolerance; for a real-time recording each of its firings happens at its "
                    "recorded time unless --free); print the first divergence with the events around it; "
                    "exit 0 only when they agree. With --live: republish every message on its zenoh key at "
                    "the recorded pace.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording (from 'iotad run' or 'iotad record')")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--node", metavar="PATH", help="the node to re-run and compare")
    what.add_argument("--live", action="store_true", help="republish the recording on zenoh")
    parser.add_argument("--tolerance", type=nonnegative_float, default=None, metavar="T",
                        help="allowed time difference, spec time units (default: exact for virtual-time "
                             "recordings, 10 ms for real ones); replaying at the recorded times, values are "
                             "compared and times are the recording's: 'iotad check' judges each firing's window")
    parser.add_argument("--internal", action="store_true", help="compare internal events too, not only outputs")
    parser.add_argument("--free", action="store_true",
                        help="let the node fire on its own at the earliest times its spec allows, and compare "
                             "times too (the default for virtual-time recordings; a real-time recording is "
                             "replayed with each firing at its recorded time)")
    parser.add_argument("--rate", type=positive_float, default=1.0, metavar="R",
                        help="--live: speed factor, 2 = twice as fast (default 1)")
    parser.add_argument("--start", type=nonnegative_float, default=0.0, metavar="S",
                        help="--live: skip the first S seconds of the recording (default 0)")
    parser.add_argument("--loop", action="store_true", help="--live: start again at the end (Ctrl-C stops)")
    parser.add_argument("--connect", action="append", default=[], metavar="EP", type=endpoint,
                        help="--live: zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    parser.add_argument("--listen", action="append", default=None, metavar="EP", type=endpoint,
                        help="--live: zenoh endpoint to listen on (default tcp/127.0.0.1:0)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.mcap_format import RecordingError
    from iotad.recording.replay import default_tolerance, replay_node

    if args.live and (args.internal or args.free or args.tolerance is not None):
        raise CliError("--internal, --free and --tolerance apply to --node, not --live")
    if not args.live and (args.rate != 1.0 or args.start or args.loop):
        raise CliError("--rate, --start and --loop are the pace of --live: give --live too")
    recording = load(args.file)
    if args.live:
        return live(args, recording)
    nodes = recording.nodes()
    if args.node not in nodes and args.node not in recording.specs:
        parts = [node for node in nodes if node.startswith(args.node + "/")]
        if parts:  # a composite node: one process in real time, its parts' traces in virtual time
            raise CliError(f"{args.node!r} is a composite whose parts this recording holds one by one: replay "
                           f"each ({', '.join('--node ' + part for part in parts)})")
        raise CliError(f"node {args.node!r} is not in {args.file} (nodes: {', '.join(nodes) or 'none'})")
    tolerance = default_tolerance(recording) if args.tolerance is None else args.tolerance
    kinds = ("output", "internal") if args.internal else ("output",)
    try:
        result = replay_node(recording, args.node, tolerance, kinds, guided=False if args.free else None)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    print("\n".join(result.lines()))
    return 0 if result.ok else 1


def live(args: argparse.Namespace, recording) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from iotad.cli import CliError
    from iotad.recording.replay import republish
    from iotad.node_host.transport import DEFAULT_LISTEN, open_session

    if not RATE_MIN <= args.rate <= RATE_MAX:  # a pace no wait could keep (sleeps past any clock's range)
        raise CliError(f"--rate {args.rate:g}: give a speed factor from {RATE_MIN:g} to {RATE_MAX:g}")
    if args.start and args.start > recording.duration():
        raise CliError(f"--start {args.start:g}: past the end of the recording ({recording.duration():.3g} s long)")
    try:
        # A peer named with --connect must answer: publishing into the void is not a replay.
        session = open_session(args.listen or DEFAULT_LISTEN, args.connect,
                               connect_timeout=3.0 if args.connect else None)
    except Exception as exc:  # noqa: BLE001 - zenoh.ZError: no peer there, or a port taken
        reason = str(exc).split(" at /", 1)[0]
        raise CliError(f"cannot open a zenoh session (listen {args.listen or list(DEFAULT_LISTEN)}, "
                       f"connect {args.connect}): {reason}") from None
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
