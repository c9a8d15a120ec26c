"""`iotad record`: record every event of a running system to MCAP until SIGINT or SIGTERM."""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from pathlib import Path

ORDER = 30


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "record", help="record a running system (every event, specs, gaps) to an MCAP file",
        description="Record every external event and every node's @trace (internal events and "
                    "violations) of a running system to MCAP, with the system file and each node's spec, "
                    "so that 'iotad replay' and 'iotad check' need nothing else. Stops cleanly on "
                    "SIGINT/SIGTERM; a killed recording loses at most the last --flush-period seconds "
                    "and is made whole by 'iotad recover'.",
        epilog="example: iotad record 'iota/figure2/**' -o recordings/fig2.mcap")
    parser.add_argument("keys", nargs="*", metavar="KEYEXPR",
                        help="zenoh key expressions; 'iota/SYS/**' also covers SYS's @trace, @launcher "
                             "and @heartbeat keys (default: every key of the system file's system)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="MCAP file to write")
    parser.add_argument("--system-file", metavar="SYSTEM.toml", help="system file to store in the recording")
    parser.add_argument("--connect", action="append", default=[], metavar="EP",
                        help="zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    parser.add_argument("--listen", action="append", default=None, metavar="EP",
                        help="zenoh endpoint to listen on (default tcp/127.0.0.1:0)")
    parser.add_argument("--flush-period", type=float, default=0.05, metavar="S",
                        help="close the MCAP chunk in progress this often (default 0.05 s)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop by itself after S seconds")
    parser.add_argument("--ready-file", metavar="PATH",
                        help="create PATH once subscribed (for launchers and tests to wait on)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.recorder import Recorder
    from iotad.transport import DEFAULT_LISTEN

    if args.flush_period <= 0 or args.flush_period > 10:
        raise CliError("--flush-period must be in (0, 10] seconds")
    try:
        recorder = Recorder(args.keys, args.output, system_file=args.system_file, connect=args.connect,
                            listen=args.listen or DEFAULT_LISTEN, flush_period=args.flush_period,
                            background=True)  # a process of its own: yield the CPU to the nodes
    except (OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    try:
        recorder.start()
    except Exception as exc:  # noqa: BLE001 - zenoh or the file system said no
        raise CliError(f"cannot start recording: {exc}") from None
    try:
        if args.ready_file:
            Path(args.ready_file).write_text(str(recorder.output))
        if not args.quiet:
            print(f"recording {' '.join(recorder.keys)} -> {recorder.output} (Ctrl-C to stop)", file=sys.stderr)
        deadline = None if args.duration is None else time.monotonic() + args.duration
        while not stop.is_set():
            timeout = 0.5 if deadline is None else min(0.5, max(0.0, deadline - time.monotonic()))
            stop.wait(timeout)
            if deadline is not None and time.monotonic() >= deadline:
                break
    finally:
        stats = recorder.stop()
    if not args.quiet:
        print(f"recorded {stats['written']} messages to {recorder.output}; "
              f"{stats['gaps']} sequence gaps ({stats['missing']} missing)", file=sys.stderr)
    return 0
