"""`iotad pub KEY JSON`: publish a value (msgpack, with the `[seq, send_time_ns]` attachment) as a
node would, e.g. to inject an input: `iotad pub iota/figure2/scheduler/req/0 '{"control": ...}'`."""
from __future__ import annotations

import argparse
import json
import time

from .ls import add_connect, tool_session

ORDER = 42


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("pub", help="publish a JSON value on a key", description=__doc__)
    parser.add_argument("key")
    parser.add_argument("value", help="the value as JSON ('null' for a channel without a value)")
    parser.add_argument("--count", type=int, default=1, metavar="N", help="publish N times (default 1; 0: forever)")
    parser.add_argument("--rate", type=float, default=1.0, metavar="HZ", help="messages per second (default 1)")
    parser.add_argument("--wait", type=float, default=2.0, metavar="S",
                        help="wait up to S seconds for a subscriber before the first message (default 2)")
    add_connect(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    import zenoh

    from iotad import wire
    from iotad.cli import CliError

    try:
        value = json.loads(args.value)
    except json.JSONDecodeError as exc:
        raise CliError(f"value is not JSON: {exc.msg} (quote it for the shell: '{{\"w\": 1.0}}')") from None
    if args.rate <= 0:
        raise CliError("--rate must be positive")
    payload = wire.encode(value)
    session = tool_session(args)
    try:
        publisher = session.declare_publisher(args.key, congestion_control=zenoh.CongestionControl.BLOCK)
        # A put before the subscriber's declaration reached us would be lost: wait for a match.
        end = time.monotonic() + args.wait
        while not publisher.matching_status.matching and time.monotonic() < end:
            time.sleep(0.01)
        if not publisher.matching_status.matching:
            print(f"iotad pub: no subscriber matches {args.key} (yet); publishing anyway", file=sys.stderr)
        period, start, sequence = 1.0 / args.rate, time.monotonic(), 0
        while args.count == 0 or sequence < args.count:
            publisher.put(payload, attachment=wire.encode_attachment(sequence))
            sequence += 1
            if args.count and sequence >= args.count:
                break
            delay = start + sequence * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        publisher.undeclare()
        return 0
    except KeyboardInterrupt:
        return 0
    finally:
        session.close()
