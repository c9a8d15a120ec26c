"""`iotad view`: watch a running system in Foxglove. A Foxglove WebSocket server (foxglove-sdk)
bridges every channel of every live node, with its JSON schema; joint states and planar poses
also in Foxglove's well-known schemas (3D and plot panels), the schedulers' acks, `mdl_command`
and every violation on /log, CAN frames decoded by name (iotad/recording/foxglove_mapping.py)."""
from __future__ import annotations

import argparse
import queue
import sys
import time

from iotad.cli import CliError, port, positive_float
from iotad.cli.live import add_connect, tool_session

ORDER = 46

EPILOG = """\
examples (with a system running, e.g. 'iotad run examples/figure2.toml' in another terminal):
  iotad view                            bridge every system on the default hub to ws://127.0.0.1:8765
  iotad view examples/figure2.toml      the hub and system that file names
  iotad view --port 9000 --until 60     another port; stop after 60 s
  iotad run examples/figure2.toml --view    start the viewer with the system

Then in Foxglove: Open connection -> Foxglove WebSocket -> ws://127.0.0.1:8765.
The server listens on loopback only unless --host says otherwise (it has no authentication)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("view", help="serve a running system to Foxglove (WebSocket), live",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("system_file", nargs="?", metavar="SYSTEM.toml",
                        help="take the hub endpoint and the system name from this file")
    parser.add_argument("--system", metavar="NAME", help="only this system (default: the file's, or every system)")
    parser.add_argument("--host", default="127.0.0.1", help="address the WebSocket server listens on (default 127.0.0.1)")
    parser.add_argument("--port", type=port, default=8765, help="WebSocket port (default 8765; 0: any free port)")
    parser.add_argument("--until", type=positive_float, metavar="S", help="stop after S seconds (default: Ctrl-C)")
    add_connect(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import zenoh

    from iotad.node_host import wire

    if args.system_file:
        from iotad.node_host.transport import reachable
        from iotad.launcher.system.system_file import SystemFileError, load_system

        try:
            system = load_system(args.system_file)
        except SystemFileError as exc:
            raise CliError("; ".join(exc.errors)) from None
        args.system = args.system or system.name
        if not args.connect:
            args.connect = [reachable(e) for e in system.listen]
    try:
        import foxglove
    except ImportError:
        raise CliError("iotad view needs foxglove-sdk: pip install 'foxglove-sdk>=0.14'") from None
    from iotad.recording.foxglove_live import Bridge

    if args.host not in ("127.0.0.1", "localhost", "::1"):
        print(f"iotad view: warning: listening on {args.host}: anyone who reaches it sees the system "
              "(no authentication)", file=sys.stderr)
    from iotad.recording.foxglove_latched import subscriptions

    session = tool_session(args)
    server = None
    try:
        inbox: queue.SimpleQueue = queue.SimpleQueue()
        try:
            server = foxglove.start_server(name=f"iotad {args.system or ''}".strip(), host=args.host, port=args.port,
                                           asset_handler=Bridge.asset,  # the arm's meshes (package:// URLs)
                                           server_listener=subscriptions(inbox.put))  # late viewers: latched state
        except Exception as exc:  # noqa: BLE001 - port taken, bad address: one line
            raise CliError(f"cannot serve on {args.host}:{args.port}: {exc}") from None
        bridge = Bridge()
        scope = f"{wire.PREFIX}/{args.system or '*'}"
        session.liveliness().declare_subscriber(
            f"{scope}/**/{wire.ALIVE}", lambda s: inbox.put(("alive", str(s.key_expr), s.kind == zenoh.SampleKind.PUT)),
            history=True)
        for key in (f"{scope}/**/{wire.TRACE}", f"{scope}/**"):
            session.declare_subscriber(key, lambda s: inbox.put(
                ("data", str(s.key_expr), s.payload.to_bytes(),
                 None if s.attachment is None else s.attachment.to_bytes())))
        print(f"iotad view: serving {args.system or 'every system'} on ws://{args.host}:{server.port} "
              f"(Foxglove: Open connection -> Foxglove WebSocket); Ctrl-C stops", flush=True)
        end = None if args.until is None else time.monotonic() + args.until
        asked: set[str] = set()
        try:
            while end is None or time.monotonic() < end:
                try:
                    item = inbox.get(timeout=0.1)
                except queue.Empty:
                    continue
                _handle(bridge, session, item, asked, wire)
        except KeyboardInterrupt:
            pass
        print(f"iotad view: {bridge.sent} messages bridged", flush=True)
        return 0
    finally:
        if server is not None:
            server.stop()
        session.close()


def _handle(bridge, session, item, asked, wire) -> None:
    if item[0] == "subscribed":  # a viewer subscribed: the latest URDF, meshes, arena... for it
        bridge.latched.resend(item[1])
        return
    if item[0] == "alive":
        _, key, present = item
        if present and key not in asked:
            asked.add(key)
            try:
                for answer in session.get(key[:-len(wire.ALIVE)] + wire.SPEC, timeout=1.0):
                    if answer.ok is not None:
                        bridge.describe(wire.decode(answer.ok.payload.to_bytes()))
            except Exception:  # noqa: BLE001 - a node gone meanwhile: its channels get a generic schema
                pass
        return
    _, key, payload, attachment = item
    try:
        value = wire.decode(payload)
        meta = wire.decode_attachment(attachment)
    except wire.WireError:
        return  # a malformed sample: the recorder counts those; a viewer shows what it can
    stamp = meta[1] if meta and meta[1] else time.time_ns()
    if key.endswith("/" + wire.TRACE):
        try:
            events = wire.trace_events(value)
        except wire.WireError:
            return
        bridge.trace("/".join(key.split("/")[2:-1]), events, stamp)
    elif "/@" not in key:
        bridge.message(key, value, stamp)
