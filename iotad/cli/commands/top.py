"""`iotad top`: a live terminal dashboard of a running system: nodes with their state, restarts
and heartbeats, message rates and p99 latency per channel, who holds the motors, and the
violations as they arrive. It only listens (liveliness, heartbeats, traces, channel keys), so it
can be started and stopped at any time, also over SSH."""
from __future__ import annotations

import argparse
import queue
import sys
import time

from iotad.cli import positive_float
from iotad.cli.live import add_connect, tool_session

ORDER = 45

EPILOG = """\
examples (with a system running, e.g. 'iotad run examples/figure2.toml' in another terminal):
  iotad top                             every system on the default hub, refreshed live
  iotad top --system figure2            one system
  iotad top --once 3                    listen 3 s, print one snapshot and exit (logs, scripts)

Latency is from the sender's send stamp to this tool's receipt (same machine clock).
Ctrl-C quits."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("top", help="live dashboard: nodes, rates, latency, motor holder, violations",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--system", metavar="NAME", help="only this system (default: every system on the hub)")
    parser.add_argument("--window", type=positive_float, default=5.0, metavar="S",
                        help="seconds over which rates and p99 latency are computed (default 5)")
    parser.add_argument("--refresh", type=positive_float, default=0.5, metavar="S",
                        help="screen refresh period (default 0.5 s)")
    parser.add_argument("--once", type=positive_float, metavar="S",
                        help="listen S seconds, print one snapshot and exit")
    add_connect(parser)
    parser.set_defaults(func=run)


def _path(key: str, system: str | None, suffix: str | None) -> tuple[str, str]:
    """(node path as shown, system) of a key iota/<system>/<path>[/<suffix>]."""
    parts = key.split("/")
    body = parts[2:-1] if suffix else parts[2:]
    path = "/".join(body)
    return (path if system else f"{parts[1]}/{path}"), parts[1]


def run(args: argparse.Namespace) -> int:
    import zenoh

    from iotad.cli.dashboard import Dashboard
    from iotad.node_host import wire

    system = args.system
    scope = f"{wire.PREFIX}/{system or '*'}"
    board = Dashboard(system, window=args.window)
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    session = tool_session(args)
    try:
        def on_alive(sample):
            inbox.put(("alive", str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

        def on_sample(sample):
            attachment = None if sample.attachment is None else sample.attachment.to_bytes()
            inbox.put(("data", str(sample.key_expr), sample.payload.to_bytes(), attachment))

        session.liveliness().declare_subscriber(f"{scope}/**/{wire.ALIVE}", on_alive, history=True)
        for key in (f"{scope}/**/{wire.HEARTBEAT}", f"{scope}/**/{wire.TRACE}", f"{scope}/**"):
            session.declare_subscriber(key, on_sample)
        asked: set[str] = set()
        end = None if args.once is None else time.monotonic() + args.once
        live = None
        if args.once is None:
            from rich.live import Live
            live = Live(board.render(), refresh_per_second=max(1, round(1 / args.refresh)), screen=False)
            live.start()
        try:
            next_draw = time.monotonic()
            while end is None or time.monotonic() < end:
                try:
                    item = inbox.get(timeout=0.05)
                except queue.Empty:
                    item = None
                if item is not None:
                    _handle(board, item, system, session, asked, wire)
                if live is not None and time.monotonic() >= next_draw:
                    next_draw = time.monotonic() + args.refresh
                    live.update(board.render())
        except KeyboardInterrupt:
            pass
        finally:
            if live is not None:
                live.update(board.render())
                live.stop()
        if args.once is not None:
            from rich.console import Console
            Console(file=sys.stdout, width=160).print(board.render())
            if not board.nodes:  # a script reading the snapshot learns that nothing answered
                where = f"of system {system!r} " if system else ""
                print(f"iotad top: no node {where}showed itself within {args.once:g} s", file=sys.stderr)
                return 1
        return 0
    finally:
        session.close()


def _handle(board, item, system, session, asked, wire) -> None:
    if item[0] == "alive":
        _, key, present = item
        path, _ = _path(key, system, wire.ALIVE)
        board.alive(path, present)
        if present and key not in asked:
            asked.add(key)
            base = key[:-len(wire.ALIVE) - 1]
            try:
                for answer in session.get(f"{base}/{wire.SPEC}", timeout=1.0):
                    if answer.ok is not None:
                        board.spec(path, wire.decode(answer.ok.payload.to_bytes()))
            except Exception:  # noqa: BLE001 - a node gone meanwhile, an odd answer: no requester names
                board.ignored += 1
        return
    _, key, payload, attachment = item
    try:
        value = wire.decode(payload)
    except wire.WireError:
        board.ignored += 1
        return
    if key.endswith("/" + wire.HEARTBEAT):
        board.heartbeat(_path(key, system, wire.HEARTBEAT)[0], value)
    elif key.endswith("/" + wire.TRACE):
        board.trace(_path(key, system, wire.TRACE)[0], wire.trace_events(value))
    elif "/@" not in key:
        try:
            meta = wire.decode_attachment(attachment)
        except wire.WireError:
            meta = None
        board.message(key if system is None else key.split("/", 2)[2], meta[1] if meta else None)
