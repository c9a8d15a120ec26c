"""How many threads zenoh receives on, in the processes of a system spread over hosts.

zenoh (1.10) closes a TCP or TLS link whose peer went silent (the lease ran out: a cut network)
on one of its receive threads, and that close blocks the thread: the socket has SO_LINGER 10 s,
fixed when zenoh was built, and a cut link always holds unacknowledged bytes (keep-alives at
least), so the kernel holds the close until the link heals or 10 s pass (eclipse-zenoh/zenoh
issues 1101, 2718). zenoh receives on 2 threads by default: a process that meshes with two or
more processes of a host that was cut off has every receive thread blocked at once, and hears
nothing for up to 10 s, its own host's processes included. The hub's launcher then missed the
heartbeats of its own nodes and killed them as frozen, and its recorder recorded nothing, while
the nodes ran on time (tests/hosts/test_a_partition_longer_than_the_lease_heals_and_both_sides_recorded_it.py).

So every process of such a run gets a receive thread for each zenoh session that may sit on
another host, and a few more: `ZENOH_RUNTIME` (read by zenoh when a process opens its first
session; children inherit it). Set here by the launcher, before its own first session, unless
the user set it."""
from __future__ import annotations

import os
from typing import MutableMapping

ENV = "ZENOH_RUNTIME"
DEFAULT_RX = 2      # zenoh's own receive threads: the ones left for live links
PER_HOST = 4        # sessions of each other host besides its nodes: launcher, recorder, agent, a tool
MAX_RX = 64         # an idle thread costs little, but not nothing


def rx_threads(remote_sessions: int) -> int:
    """Receive threads for a process that may hold links to `remote_sessions` sessions on other
    hosts: one for each (each may block for the whole linger) and zenoh's own two beside them."""
    return max(DEFAULT_RX, min(MAX_RX, DEFAULT_RX + max(0, remote_sessions)))


def remote_sessions(system, host: str | None) -> int:
    """How many zenoh sessions of `system` may run on hosts other than `host`: their nodes, their
    buses' loggers and, per host, its launcher, recorder, agent and a tool."""
    hosts = {node.host for node in system.nodes.values() if node.host}
    others = hosts - {host}
    nodes = sum(1 for node in system.nodes.values() if node.host in others)
    return nodes + len(getattr(system, "buses", ())) + PER_HOST * len(others)


def setting(threads: int) -> str:
    return f"(rx: (worker_threads: {threads}))"


def use_for(system, host: str | None, env: MutableMapping[str, str] = os.environ) -> str | None:
    """Give this process (and the children that inherit `env`) the receive threads a system over
    hosts needs; None, and nothing changed, for a system on one host or where the user set
    ZENOH_RUNTIME already. Call before any zenoh session opens."""
    if ENV in env or len({node.host for node in system.nodes.values() if node.host}) < 2:
        return None
    env[ENV] = setting(rx_threads(remote_sessions(system, host)))
    return env[ENV]
