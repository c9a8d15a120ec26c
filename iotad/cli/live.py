"""What the commands that talk to a running system share (`ls`, `echo`, `hz`, `pub`, `top`, `view`,
`can`): the --connect options, the tool session they open with them, and the list of live nodes."""
from __future__ import annotations

import argparse

from iotad.cli import endpoint, positive_float


def add_connect(parser: argparse.ArgumentParser) -> None:
    """The options every introspection command shares."""
    from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT

    parser.add_argument("--connect", action="append", metavar="ENDPOINT", type=endpoint,
                        help=f"zenoh endpoint of the system's hub (default {DEFAULT_HUB_ENDPOINT}, where "
                             "'iotad run' puts it); repeatable")
    parser.add_argument("--connect-timeout", type=positive_float, default=3.0, metavar="S",
                        help="give up when no peer answers within S seconds (default 3)")


def tool_session(args: argparse.Namespace):
    from iotad.cli import CliError
    from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT, PeerUnreachable, open_tool_session

    try:
        return open_tool_session(args.connect or [DEFAULT_HUB_ENDPOINT], args.connect_timeout)
    except PeerUnreachable as exc:
        raise CliError(str(exc)) from None


def list_nodes(session, system: str | None, timeout: float) -> list[dict]:
    """Every live node of `system` (or of all systems), with its `@spec` answer when it gave one."""
    from iotad.node_host import wire

    pattern = f"{wire.PREFIX}/{system or '*'}/**/{wire.ALIVE}"
    nodes = []
    for reply in session.liveliness().get(pattern, timeout=timeout):
        if reply.ok is None:
            continue
        key = str(reply.ok.key_expr)
        base = key[:-len(wire.ALIVE) - 1]
        parts = base.split("/")
        node = {"system": parts[1], "path": "/".join(parts[2:]), "alive": key, "spec": None}
        for answer in session.get(f"{base}/{wire.SPEC}", timeout=timeout):
            if answer.ok is not None:
                try:
                    node["spec"] = wire.decode(answer.ok.payload.to_bytes())
                except wire.WireError:
                    pass
        nodes.append(node)
    return sorted(nodes, key=lambda n: (n["system"], n["path"]))
