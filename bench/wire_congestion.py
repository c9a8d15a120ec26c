"""What congestion control zenoh gives, on the wire, a query's reply and a declaration, read from
zenoh's own trace log of the replying process: the evidence behind docs/hosts.md, section 8
("Replies and declarations across hosts"). Prints figures; asserts nothing.

    .venv/bin/python bench/wire_congestion.py

Two processes on loopback: an asker that sends a query with BLOCK (with or without the `qos/network`
overwrite that sends queries to other hosts with DROP, as the hub, the hosts' routers and the nodes
of an open run do), and a replier with a queryable, whose zenoh logs each message it schedules on a
link (`RUST_LOG=zenoh_transport::unicast::universal::tx=trace`). For each case, the QoS of every
Response, ResponseFinal and Declare the replier sent: a reply takes the QoS its query arrived with
(zenoh 1.10; zenoh's overwrite itself takes only puts, deletes and queries), and declarations go
at the control priority with BLOCK, whatever the overwrite.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

# zenoh's config item that the hub, the hosts' routers and an open run's nodes carry (among others)
OVERWRITE = [{"id": "queries-drop", "messages": ["put", "delete", "query"], "flows": ["egress"],
              "overwrite": {"congestion_control": "drop"}}]
TRACE = "zenoh_transport::unicast::universal::tx=trace"
SCHEDULED = re.compile(r"Scheduled NetworkMessageRef \{ body: (\w+)\(.*?ext_qos: QoS \{ priority: (\w+), congestion: (\w+)")


def ask(port: int, overwrite: bool) -> None:
    import zenoh

    from iotad.node_host.transport import open_session

    with open_session([f"tcp/127.0.0.1:{port}"], [], extra={"qos/network": OVERWRITE} if overwrite else {},
                      credentials=False) as asker:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # until the replier has linked and declared its queryable
            if any(r.ok is not None for r in asker.get("bench/q", congestion_control=zenoh.CongestionControl.BLOCK,
                                                       timeout=0.5)):
                break
            time.sleep(0.1)
        time.sleep(0.3)


def reply(port: int, seconds: float) -> None:
    import zenoh

    from iotad.node_host.transport import free_port, open_session

    zenoh.init_log_from_env_or("error")
    with open_session([f"tcp/127.0.0.1:{free_port()}"], [f"tcp/127.0.0.1:{port}"], credentials=False) as replier:
        replier.declare_queryable("bench/q", lambda query: query.reply("bench/q", b"x"))
        time.sleep(seconds)


def wire_qos(overwrite: bool) -> dict[str, set[tuple[str, str]]]:
    """The (priority, congestion control) of each kind of message the replier scheduled on its link
    to an asker whose queries leave with DROP (`overwrite`) or as sent (BLOCK)."""
    from iotad.node_host.transport import free_port

    port = free_port()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    asker = subprocess.Popen([sys.executable, __file__, "--ask", str(port), *(["--overwrite"] if overwrite else [])],
                             env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        replier = subprocess.run([sys.executable, __file__, "--reply", str(port)], env={**env, "RUST_LOG": TRACE},
                                 capture_output=True, text=True, timeout=60)
    finally:
        asker.wait(30)
    found: dict[str, set[tuple[str, str]]] = {}
    for body, priority, congestion in SCHEDULED.findall(re.sub(r"\x1b\[[0-9;]*m", "", replier.stdout + replier.stderr)):
        found.setdefault(body, set()).add((priority, congestion))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ask", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--reply", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--overwrite", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.ask:
        return ask(args.ask, args.overwrite)
    if args.reply:
        return reply(args.reply, 3.0)
    for overwrite in (False, True):
        found = wire_qos(overwrite)
        what = "queries overwritten to DROP on the asker's egress" if overwrite else "queries as sent (BLOCK)"
        print(f"{what}:")
        for body in ("Response", "ResponseFinal", "Declare"):
            shown = ", ".join(f"{p} {c}" for p, c in sorted(found.get(body, ()))) or "none seen"
            print(f"  {body}: {shown}")


if __name__ == "__main__":
    main()
