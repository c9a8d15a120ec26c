"""`iotad can`: bring-up on a real CAN bus: which drives answer (ODrive and CiA 402), their state, and commands read back.

Units are SI at this interface: velocity in rad/s at the motor shaft, torque in N.m, current in A.
Turns appear only on the wire (ODrive CAN Simple), increments only in CANopen objects.
"""
from __future__ import annotations

import argparse
import sys
import time

ORDER = 38

EPILOG = """\
examples:
  iotad can scan --interface socketcan --channel can0      every drive that answers, with its state
  iotad can scan --system examples/arm_can.toml            the bus of the system file's [[can]]
  python -m iotad.can.tiers run -- .venv/bin/iotad can scan   the tier's bus (IOTAD_CAN_INTERFACE)
  iotad can status --watch --period 1 --interface socketcan --channel can0
  iotad can clear-errors --node 3 ...    |  arm --node 3  |  idle --node 3  |  estop --node 3
  iotad can set-limits --node 3 --velocity 6.28 --current 20   (ODrive: rad/s at the motor, A)
  iotad can set-limits --node 5 --velocity 6.28 --torque 2.5   (CiA 402: rad/s at the motor, N.m)

Units are SI here: rad/s at the motor shaft, N.m, A. On the wire an ODrive gets turns/s
(rad/s / 2 pi) and a CiA 402 drive increments/s (by its 0x608F resolution); nothing else changes.
A command reads its result back and says in words what the drive reports when it is not the one
asked for, or that nothing answered in time (exit 1). A command is refused on an axis that a
running system's motor node holds (its liveliness token and @spec on the zenoh hub, --connect),
unless --force. --protocol says which family when a node id answers as both. docs/can.md."""

COMMANDS = ("scan", "status", "clear-errors", "arm", "idle", "set-limits", "estop")


def register(sub: argparse._SubParsersAction) -> None:
    from iotad.cli import nonnegative_float, positive_float, positive_int

    from iotad.cli.live import add_connect

    parser = sub.add_parser("can", help="bring-up on a CAN bus: scan drives, their status, clear errors, arm, idle, "
                                        "limits, estop (SI units; turns only on the wire)",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("action", choices=COMMANDS, help="what to do")
    parser.add_argument("--node", type=int, metavar="N", help="the drive's node id (commands)")
    parser.add_argument("--protocol", choices=("odrive", "cia402"), help="the drive's family, where a node id answers as both")
    parser.add_argument("--system", metavar="SYSTEM.toml", help="use this system file's [[can]] bus")
    parser.add_argument("--bus", metavar="NAME", help="which [[can]] bus of the system file (default: its only one)")
    parser.add_argument("--interface", help="python-can interface: socketcan | udp_multicast | virtual (default: the tier's)")
    parser.add_argument("--channel", help="python-can channel: vcan0, can0, a multicast group")
    parser.add_argument("--velocity", type=positive_float, metavar="RAD_S", help="set-limits: velocity limit, rad/s at the motor shaft")
    parser.add_argument("--current", type=positive_float, metavar="A", help="set-limits: current limit, A (ODrive)")
    parser.add_argument("--torque", type=positive_float, metavar="NM", help="set-limits: torque limit, N.m (CiA 402)")
    parser.add_argument("--timeout", type=positive_float, default=1.0, metavar="S",
                        help="how long a command waits for its result (default 1 s)")
    parser.add_argument("--heartbeat-period", type=positive_float, default=0.1, metavar="S",
                        help="an ODrive's cyclic Heartbeat period: its state is read from the next heartbeat, "
                             "waited for up to 1.5 periods (then a remote request) (default 0.1 s, the firmware's)")
    parser.add_argument("--watch", action="store_true", help="status: refresh the table until Ctrl-C")
    parser.add_argument("--period", type=positive_float, default=1.0, metavar="S", help="status --watch: seconds between tables")
    parser.add_argument("--count", type=positive_int, metavar="N", help="status --watch: stop after N tables")
    parser.add_argument("--force", action="store_true", help="command an axis even though a running motor node holds it")
    parser.add_argument("--hub-timeout", type=nonnegative_float, default=1.0, metavar="S",
                        help="seconds to look for running systems on the zenoh hub (0: do not look)")
    add_connect(parser)
    parser.set_defaults(func=run, connect_timeout=1.0)


def run(args: argparse.Namespace) -> int:
    from iotad.can.bringup import CommandFailed, Link
    from iotad.can.bus import BusUnavailable
    from iotad.cli import CliError

    if args.action in ("scan", "status"):
        if args.node is not None and args.action == "scan":
            raise CliError("scan looks at every node id; use 'status --node N' for one")
    elif args.node is None:
        raise CliError(f"{args.action} needs --node N")
    if args.action != "set-limits" and (args.velocity or args.current or args.torque):
        raise CliError("--velocity, --current and --torque are for set-limits")
    try:
        bus = _open(args)
    except BusUnavailable as exc:
        raise CliError(str(exc)) from None
    with bus:
        link = Link(bus, heartbeat_period=args.heartbeat_period)
        print(f"iotad can: {bus.describe()}", file=sys.stderr, flush=True)
        try:
            if args.action in ("scan", "status"):
                return _table(link, args)
            protocol = _protocol(link, args)
            _refuse_if_held(args, protocol)
            return _command(link, args, protocol)
        except CommandFailed as exc:
            print(f"iotad can: {args.action} failed: {exc}", file=sys.stderr)
            return 1


def _open(args: argparse.Namespace):
    from iotad.cli.can_bus import live_bus

    view = argparse.Namespace(source=args.system, bus=args.bus, interface=args.interface, channel=args.channel)
    return live_bus(view)


def _table(link, args: argparse.Namespace) -> int:
    from iotad.can import bringup

    shown = 0
    while True:
        if args.node is not None:
            protocols = [args.protocol] if args.protocol else _answering(link, args.node)
            drives = [bringup.status(link, p, args.node) for p in protocols]
        else:
            drives = bringup.scan(link, [args.protocol] if args.protocol else ("odrive", "cia402"))
        if args.watch:
            print(time.strftime("%H:%M:%S"), flush=True)
        print(format_table(drives), flush=True)
        shown += 1
        if not args.watch or (args.count and shown >= args.count):
            return 0 if drives else 1
        try:
            time.sleep(args.period)
        except KeyboardInterrupt:
            return 0


def format_table(drives) -> str:
    if not drives:
        return "no drive answered"
    rows = [("protocol", "node", "firmware", "hardware", "state", "errors", "bus V", "temp C", "state from", "device")]
    for d in drives:
        rows.append((d.protocol, str(d.node_id), d.firmware, d.hardware, d.state, ", ".join(d.errors) or "none",
                     "-" if d.bus_voltage is None else f"{d.bus_voltage:.1f}",
                     "-" if d.temperature is None else f"{d.temperature:.0f}", d.source or "-",
                     d.detail.get("device", "-")))
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in rows)


def _answering(link, node: int) -> list[str]:
    from iotad.can import bringup

    found = []
    if 0 <= node <= 63 and bringup.scan_odrives(link, [node]):
        found.append("odrive")
    if 1 <= node <= 127 and bringup.scan_cia402(link, [node], avoid=[node] if found else ()):
        found.append("cia402")
    return found


def _protocol(link, args: argparse.Namespace) -> str:
    from iotad.can.bringup import CommandFailed

    if args.protocol:
        return args.protocol
    found = _answering(link, args.node)
    if not found:
        raise CommandFailed(f"node {args.node}: no ODrive (Get_Version) or CiA 402 drive (SDO 0x1018) answered "
                            f"within {link.timeout:g} s")
    if len(found) > 1:
        raise CommandFailed(f"node {args.node} answers as an ODrive and as a CiA 402 drive: say which with --protocol")
    return found[0]


def held_axes(args: argparse.Namespace) -> dict[tuple[str, int], str]:
    """{(protocol, node id): "system/node"} of the axes that running motor nodes hold: each live
    node (liveliness token @alive) whose @spec params carry a joint map."""
    if not args.hub_timeout:
        return {}
    from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT, PeerUnreachable, open_tool_session

    from iotad.cli.live import list_nodes

    try:
        session = open_tool_session(args.connect or [DEFAULT_HUB_ENDPOINT], args.hub_timeout)
    except PeerUnreachable:
        return {}  # no hub: no system runs here
    try:
        nodes = list_nodes(session, None, args.hub_timeout)
    finally:
        session.close()
    held = {}
    for node in nodes:
        params = (node.get("spec") or {}).get("params") or {}
        joints = params.get("joints") if isinstance(params, dict) else None
        entries = joints.values() if isinstance(joints, dict) else joints if isinstance(joints, list) else ()
        for joint in entries:
            if isinstance(joint, dict) and isinstance(joint.get("node_id"), int):
                held[(joint.get("protocol", "odrive"), joint["node_id"])] = f"{node['system']}/{node['path']}"
    return held


def _refuse_if_held(args: argparse.Namespace, protocol: str) -> None:
    from iotad.cli import CliError

    if args.force:
        return
    holder = held_axes(args).get((protocol, args.node))
    if holder:
        raise CliError(f"node {args.node} ({protocol}) is held by the running motor node {holder}: a command now "
                       "would fight it (it stops a drive armed behind its back); an axis it holds in FAULT is "
                       f"re-armed by its reset: iotad pub iota/{holder}/estop false; or stop that system, "
                       "or give --force")


def _command(link, args: argparse.Namespace, protocol: str) -> int:
    from iotad.can import bringup

    node, timeout = args.node, args.timeout
    if args.action == "set-limits":
        if args.velocity is None and args.current is None and args.torque is None:
            from iotad.cli import CliError
            raise CliError("set-limits needs --velocity (rad/s), and --current (A, ODrive) or --torque (N.m, CiA 402)")
        result = bringup.set_limits(link, protocol, node, args.velocity, args.current, args.torque)
        print(f"node {node} ({protocol}): limits " + ", ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
                                                              for k, v in result.items()))
        return 0
    action = {"clear-errors": bringup.clear_errors, "arm": bringup.arm, "idle": bringup.idle,
              "estop": bringup.estop}[args.action]
    drive = action(link, protocol, node, timeout)
    read = _read_back(drive)
    if drive.detail.get("unchanged"):
        print(f"node {node} ({protocol}): {args.action}: no fault, nothing sent; it reports {drive.state}{read}")
        return 0
    print(f"node {node} ({protocol}): {args.action} done: {drive.state}, errors: {', '.join(drive.errors) or 'none'}{read}")
    return 0


def _read_back(drive) -> str:
    """Where the state shown came from: the drive's statusword, its cyclic heartbeat, or a remote request."""
    if "statusword" in drive.detail:
        return f" (statusword 0x{drive.detail['statusword']:04X})"
    return f" (from its {drive.source})" if drive.source else ""
