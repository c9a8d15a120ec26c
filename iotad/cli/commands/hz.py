"""`iotad hz KEYEXPR`: the rate of messages on a key expression, like `ros2 topic hz`: once a
second, the average rate and the min/max/std dev of the period over the last W messages."""
from __future__ import annotations

import argparse
import math
import queue
import time

from iotad.cli import key_expression, positive_float, positive_int

from iotad.cli.live import add_connect, tool_session

ORDER = 43

EPILOG = """\
examples (with 'iotad run examples/figure2.toml' running in another terminal):
  iotad hz iota/figure2/scheduler/@heartbeat          about 5 Hz (heartbeat_period 0.2 s)
  iotad hz 'iota/figure2/*/req' --every 5 --count 3

Rates are messages per second of wall-clock time, periods in seconds, measured on arrival.
Ctrl-C stops (exit 130). See also: 'iotad echo KEY', 'iotad ls'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("hz", help="measure the publishing rate on a key expression (like ros2 topic hz)",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("keyexpr", metavar="KEYEXPR", type=key_expression,
                        help="e.g. iota/figure2/scheduler/@heartbeat or 'iota/figure2/**'")
    parser.add_argument("--window", type=int, default=1000, metavar="W",
                        help="statistics over the periods of the last W messages (default 1000, at least 2)")
    parser.add_argument("--count", type=positive_int, metavar="N", help="exit after N reports (default: never)")
    parser.add_argument("--every", type=positive_float, default=1.0, metavar="S",
                        help="seconds between reports (default 1)")
    add_connect(parser)
    parser.set_defaults(func=run)


def period_stats(arrivals: list[float]) -> dict | None:
    """Rate and period statistics of arrival times (seconds), or None with fewer than two."""
    if len(arrivals) < 2:
        return None
    periods = [b - a for a, b in zip(arrivals, arrivals[1:])]
    mean = sum(periods) / len(periods)
    std = math.sqrt(sum((p - mean) ** 2 for p in periods) / len(periods))
    return {"rate": 1.0 / mean if mean > 0 else math.inf, "min": min(periods), "max": max(periods),
            "std": std, "window": len(arrivals)}


def run(args: argparse.Namespace) -> int:
    from collections import deque

    if args.window < 2:
        from iotad.cli import CliError

        raise CliError("--window must be at least 2")
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    session = tool_session(args)
    try:
        # The arrival time is taken on zenoh's thread, not when this loop gets to it.
        session.declare_subscriber(args.keyexpr, lambda sample: inbox.put(time.monotonic()))
        arrivals: deque = deque(maxlen=args.window)
        reports, next_report = 0, time.monotonic() + args.every
        while args.count is None or reports < args.count:
            remaining = next_report - time.monotonic()
            if remaining > 0:  # a steady stream must not postpone the report
                try:
                    arrivals.append(inbox.get(timeout=remaining))
                    continue
                except queue.Empty:
                    pass
            next_report += args.every
            stats = period_stats(list(arrivals))
            reports += 1
            if stats is None:
                print(f"no messages on {args.keyexpr} yet" if not arrivals else "one message so far", flush=True)
                continue
            print(f"average rate: {stats['rate']:.3f}\n\tmin: {stats['min']:.6f}s max: {stats['max']:.6f}s "
                  f"std dev: {stats['std']:.6f}s window: {stats['window']}", flush=True)
        return 0
    finally:
        session.close()
