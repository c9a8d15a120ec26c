"""`iotad ls`: the live nodes (from their liveliness tokens) and their channels (from `@spec`)."""
from __future__ import annotations

import argparse
import json

from iotad.cli import positive_float
from iotad.cli.live import add_connect, list_nodes, tool_session

ORDER = 40

EPILOG = """\
examples (with a system running, e.g. 'iotad run examples/figure2.toml' in another terminal):
  iotad ls                              every live node and its channels
  iotad ls --system figure2 --json      one JSON object per node

Each node line names its host (the system file's host = NAME, else the machine's name), its pid
and its code. Each channel line: <- input or -> output, name, type, switching time s (spec time units) and
its zenoh keys. See also: 'iotad echo KEY', 'iotad hz KEY', 'iotad pub KEY VALUE'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("ls", help="list the live nodes of running systems and their channels",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--system", metavar="NAME", help="only the nodes of this system (default: every system)")
    parser.add_argument("--json", action="store_true", help="one JSON object per node")
    parser.add_argument("--timeout", type=positive_float, default=2.0, metavar="S",
                        help="seconds to wait for answers (default 2)")
    add_connect(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    session = tool_session(args)
    try:
        nodes = list_nodes(session, args.system, args.timeout)
    finally:
        session.close()
    if args.json:
        for node in nodes:
            spec = node["spec"] or {}
            print(json.dumps({"system": node["system"], "path": node["path"], "host": spec.get("host"),
                              "pid": spec.get("pid"),
                              "source": spec.get("source"), "params": spec.get("params"),
                              "channels": [{k: c[k] for k in ("name", "direction", "type", "switching_time",
                                                              "keys", "bound")}
                                           for c in spec.get("channels", [])]}))
        return 0
    if not nodes:
        print("no live nodes" + (f" in system {args.system}" if args.system else ""))
        return 0
    for node in nodes:
        spec = node["spec"]
        if spec is None:
            print(f"{node['system']}/{node['path']}  (alive; no @spec answer)")
            continue
        source = spec.get("source", {})
        what = source.get("ref") or (f"{source.get('file')}:{source['iota']}" if source.get("iota")
                                     else str(source.get("file")))  # a file's only (or last) iota
        print(f"{node['system']}/{node['path']}  host {spec.get('host') or '?'}  pid {spec.get('pid')}  "
              f"{source.get('kind')} {what}")
        for channel in spec.get("channels", []):
            arrow = "<-" if channel["direction"] == "input" else "->"
            keys = ", ".join(channel["keys"])
            bound = [k for keys_ in channel.get("bound", {}).values() for k in keys_]
            extra = f"  (from {', '.join(bound)})" if bound else ""
            print(f"  {arrow} {channel['name']:<14} {channel['type'] or '-':<16} s={channel['switching_time']:g}  "
                  f"{keys}{extra}")
    return 0
