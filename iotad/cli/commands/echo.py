"""`iotad echo KEYEXPR`: print decoded values as they arrive, flagging gaps in sender sequences.

zenoh does not let `**` match `@`-chunks: name `@trace` or `@heartbeat` keys explicitly."""
from __future__ import annotations

import argparse
import json
import queue
import time

from iotad.cli import key_expression, positive_float, positive_int

from iotad.cli.live import add_connect, tool_session

ORDER = 41

EPILOG = """\
examples (with 'iotad run examples/figure2.toml' running in another terminal):
  iotad echo 'iota/figure2/scheduler/ack/*'           the scheduler's answers, as they come
  iotad echo iota/figure2/scheduler/@trace --json     every event of the node, one JSON a line
  iotad echo 'iota/figure2/**' --count 10 --timeout 30

Each line: key, #sequence number, value as JSON; [GAP: n missed] when the sender's sequence
numbers skip. A @trace sample is a burst of events: one line each, numbered from the burst's
sequence number. Ctrl-C stops (exit 130); --count N exits 0 after N lines; --timeout exits 1.
See also: 'iotad ls' (what keys exist), 'iotad hz KEY' (rates), 'iotad record'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("echo", help="print the values published on a key expression, as they arrive",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("keyexpr", metavar="KEYEXPR", type=key_expression,
                        help="e.g. 'iota/figure2/scheduler/ack/*' or iota/figure2/scheduler/@trace")
    parser.add_argument("--count", type=positive_int, metavar="N", help="exit after N messages (default: never)")
    parser.add_argument("--json", action="store_true",
                        help='one JSON object per message: key, seq, send_ns, value, and "gap" (messages '
                             'missed before it) or "restarted": true (the sender began again) when so')
    parser.add_argument("--timeout", type=positive_float, metavar="S",
                        help="exit with status 1 when S seconds pass before --count messages (default: wait forever)")
    add_connect(parser)
    parser.set_defaults(func=run)


class GapTracker:
    """Per key: how many messages the sender's sequence numbers say were missed."""

    def __init__(self):
        self.last: dict[str, int] = {}

    def see(self, key: str, sequence: int | None, count: int = 1) -> int:
        """`count`: how many sequence numbers the sample takes (the events of a `@trace` burst)."""
        if sequence is None:
            return 0
        expected = self.last.get(key)
        self.last[key] = sequence + count
        if expected is None or sequence == expected:
            return 0
        return sequence - expected if sequence > expected else -1  # -1: the sender restarted


def json_record(key: str, seq: int | None, send_ns: int | None, value, gap: int, malformed: str | None) -> dict:
    """One line of `--json`: "gap" counts the messages missed just before it, "restarted" says
    the sender's sequence began again (GapTracker's -1)."""
    record = {"key": key, "seq": seq, "send_ns": send_ns, "value": value}
    if gap > 0:
        record["gap"] = gap
    elif gap < 0:
        record["restarted"] = True
    if malformed:
        record["malformed"] = malformed
    return record


def run(args: argparse.Namespace) -> int:
    from iotad.node_host import wire

    inbox: queue.SimpleQueue = queue.SimpleQueue()
    session = tool_session(args)
    try:
        session.declare_subscriber(args.keyexpr, lambda s: inbox.put(
            (str(s.key_expr), s.payload.to_bytes(), None if s.attachment is None else s.attachment.to_bytes())))
        gaps, seen = GapTracker(), 0
        end = None if args.timeout is None else time.monotonic() + args.timeout
        while args.count is None or seen < args.count:
            wait = 0.2 if end is None else min(0.2, end - time.monotonic())
            if wait <= 0:
                import sys

                got = (f"{seen} of the {args.count} messages wanted" if args.count
                       else "no message" if not seen else f"{seen} messages")
                print(f"iotad echo: timeout: {got} on {args.keyexpr} within {args.timeout:g} s",
                      file=sys.stderr)
                return 1
            try:
                key, payload, attachment = inbox.get(timeout=wait)
            except queue.Empty:
                continue
            meta = wire.decode_attachment(attachment)
            sequence, send_ns = meta if meta else (None, None)
            try:
                value, malformed = wire.decode(payload), None
            except wire.WireError as exc:
                value, malformed = None, str(exc)
            values = [value]
            if key.endswith("/" + wire.TRACE) and isinstance(value, list):
                values = value  # a burst: one line per event, numbered from the burst's seq
            gap = gaps.see(key, sequence, len(values))
            for position, value in enumerate(values):
                if args.count is not None and seen >= args.count:
                    break
                seen += 1
                number = None if sequence is None else sequence + position
                if args.json:
                    print(json.dumps(json_record(key, number, send_ns, value, 0 if position else gap, malformed),
                                     default=repr), flush=True)
                    continue
                flag = ""
                if gap > 0 and not position:
                    flag = f"  [GAP: {gap} missed]"
                elif gap < 0 and not position:
                    flag = "  [sequence restarted]"
                shown = f"<{malformed}>" if malformed else json.dumps(value, default=repr)
                seq = "" if number is None else f"#{number} "
                print(f"{key} {seq}{shown}{flag}", flush=True)
        return 0
    finally:
        session.close()
