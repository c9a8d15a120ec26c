"""`iotad echo KEYEXPR`: print decoded values as they arrive, flagging gaps in sender sequences.

zenoh does not let `**` match `@`-chunks: name `@trace` or `@heartbeat` keys explicitly."""
from __future__ import annotations

import argparse
import json
import queue
import time

from .ls import add_connect, tool_session

ORDER = 41


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("echo", help="print the values published on a key expression", description=__doc__)
    parser.add_argument("keyexpr", help="e.g. iota/figure2/scheduler/ack/* or iota/figure2/scheduler/@trace")
    parser.add_argument("--count", type=int, metavar="N", help="exit after N messages")
    parser.add_argument("--json", action="store_true", help="one JSON object per message")
    parser.add_argument("--timeout", type=float, metavar="S", help="exit (code 1) if S seconds pass without "
                                                                   "--count messages")
    add_connect(parser)
    parser.set_defaults(func=run)


class GapTracker:
    """Per key: how many messages the sender's sequence numbers say were missed."""

    def __init__(self):
        self.last: dict[str, int] = {}

    def see(self, key: str, sequence: int | None) -> int:
        if sequence is None:
            return 0
        previous = self.last.get(key)
        self.last[key] = sequence
        if previous is None or sequence == previous + 1:
            return 0
        return sequence - previous - 1 if sequence > previous else -1  # -1: the sender restarted


def run(args: argparse.Namespace) -> int:
    from iotad import wire

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
                return 1
            try:
                key, payload, attachment = inbox.get(timeout=wait)
            except queue.Empty:
                continue
            seen += 1
            meta = wire.decode_attachment(attachment)
            sequence, send_ns = meta if meta else (None, None)
            gap = gaps.see(key, sequence)
            try:
                value, malformed = wire.decode(payload), None
            except wire.WireError as exc:
                value, malformed = None, str(exc)
            if args.json:
                record = {"key": key, "seq": sequence, "send_ns": send_ns, "value": value}
                if gap:
                    record["gap"] = gap
                if malformed:
                    record["malformed"] = malformed
                print(json.dumps(record, default=repr), flush=True)
                continue
            flag = ""
            if gap > 0:
                flag = f"  [GAP: {gap} missed]"
            elif gap < 0:
                flag = "  [sequence restarted]"
            shown = f"<{malformed}>" if malformed else json.dumps(value, default=repr)
            seq = "" if sequence is None else f"#{sequence} "
            print(f"{key} {seq}{shown}{flag}", flush=True)
        return 0
    except KeyboardInterrupt:
        return 0
    finally:
        session.close()
