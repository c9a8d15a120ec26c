"""The zenoh settings of a node in an open run over hosts (`--insecure`, the nodes zenoh peers that
mesh directly across the hosts): what it sends toward another host goes with congestion control
DROP, what it sends to its own host's sessions keeps the BLOCK it was published with
(docs/hosts.md, section 8).

Why: a node publishes its outputs and its trace with BLOCK, so that its host's recorder (a client
of the host's launcher, which relays to it) loses nothing. zenoh pushes a BLOCK message onto every
link that wants it, and waits while that link's queue is full: toward a host that was cut off the
queue fills (an express output takes a batch of its own, and a queue holds two a priority, behind
the socket's send buffer), and the node's put waited on the engine's thread until zenoh closed the
link (`wait_before_close`, 5 s) or the lease ran out. Measured with three hosts, arm cut for 12 s,
a pulse on brain sending 250 a second to a sink on each host: the pulse fired nothing for 3.9 to 5.7 s,
and neither its sink on brain nor the one on base heard anything meanwhile
(tests/hosts/test_a_host_cut_past_the_lease_holds_up_no_publisher_on_the_others.py).

How: zenoh's `qos/network` overwrite, on egress, in items applied in order: every put, delete and
query sent with BLOCK leaves with DROP (and batched), then those toward this host's own sessions
get back what they were sent with (`settings`). Of a link's other end zenoh's overwrite knows
its zenoh id, its interface and its protocol, and neither of the last two tells a link to this
host's launcher from one to another host (both are TCP on the host's address), so each node's session
takes an id this host's launcher derives from a secret of its own run, the node's name and its
restart count, and every node of the host is told all the ids its neighbours may have (each
restart up to the node's `max_restarts`) and the launcher's own. A restarted node has a new id,
so that the other hosts never take it for the process it replaces. A query that leaves with DROP
is answered with DROP as well (zenoh replies with the query's QoS as it reached each hop); zenoh
sends declarations with BLOCK at the control priority and does not overwrite them."""
from __future__ import annotations

import hashlib
import secrets
from typing import Iterable

# what zenoh's overwrite takes (1.10: put, delete and query; replies follow their query's QoS)
MESSAGES = ["put", "delete", "query"]


def session_id(secret: str, node: str, restarts: int) -> str:
    """The zenoh id of `node`'s session after `restarts` restarts: lowercase hex without a leading 0,
    as zenoh wants it; unique per process start, and unknown to anyone without `secret`."""
    digest = hashlib.sha256(f"iotad node session\0{secret}\0{node}\0{restarts}".encode()).hexdigest()[:32]
    return digest.lstrip("0") or "1"


# What a node publishes with BLOCK, as it leaves toward another host: DROP, and batched (not
# express), each kind under a priority of its own, so that the items toward this host's sessions
# can give each kind back exactly what it had (zenoh's overwrite keeps no note of what a message
# carried before it). A node publishes its outputs at DATA, express; its trace at DATA_LOW; its
# queries at DATA; nothing at DATA_HIGH or INTERACTIVE_LOW, the marks. Batched for the reason the
# hub's are (`host_access.across_hosts_settings`): an express message takes a batch of its own and
# a link's queue holds two a priority, so with DROP alone a hold of a few ms of the other host's
# node lost outputs (6 of 5527 in one run of the cut test, at 250 a second).
_KINDS = [  # (what it was, what leaves toward another host)
    ({"priority": "data", "congestion_control": "block", "express": True},
     {"priority": "data_high", "congestion_control": "drop", "express": False}),
    ({"priority": "data", "congestion_control": "block", "express": False},
     {"priority": "interactive_low", "congestion_control": "drop"}),
    ({"priority": "data_low", "congestion_control": "block"},
     {"congestion_control": "drop", "express": False}),
]


def settings(own: str, local: Iterable[str]) -> dict:
    """zenoh settings for a session whose id is `own`: what it sends with BLOCK leaves toward every
    other session with DROP and batched, and toward the sessions `local` (its own host's) as sent."""
    local = sorted(set(local) - {own})
    items: list[dict] = []
    for k, (was, away) in enumerate(_KINDS):
        items.append({"id": f"other-hosts-{k}", "messages": list(MESSAGES), "flows": ["egress"], "qos": was,
                      "overwrite": away})
    if local:
        for k, (was, away) in enumerate(_KINDS):
            marked = {"priority": away.get("priority", was["priority"]), "congestion_control": "drop"}
            items.append({"id": f"own-host-{k}", "zids": local, "messages": list(MESSAGES), "flows": ["egress"],
                          "qos": marked, "overwrite": dict(was)})
    return {"id": own, "qos/network": items}


class OpenHosts:
    """The node sessions of one host's launcher in an open run over hosts: their ids and settings.
    `nodes` maps each node of this host to its `max_restarts`; `launcher` is the id of the launcher's
    own session (the hub's, on the hub's host), which relays to the host's recorder."""

    def __init__(self, nodes: dict[str, int], launcher: str, secret: str | None = None):
        self.secret = secret or secrets.token_hex(16)
        self.nodes, self.launcher = dict(nodes), launcher
        self.local = [launcher] + [session_id(self.secret, node, k)
                                   for node, most in self.nodes.items() for k in range(most + 1)]

    def node_settings(self, node: str, restarts: int) -> dict:
        return settings(session_id(self.secret, node, restarts), self.local)

    @staticmethod
    def applies(system, host: str | None, secured: bool) -> bool:
        """Whether a launcher of `host` gives its nodes these settings: an open run whose nodes sit
        on two hosts or more, run by host (not `--local`, whose hosts are all this machine)."""
        return not secured and host is not None and len({n.host for n in system.nodes.values() if n.host}) >= 2


__all__ = ["MESSAGES", "OpenHosts", "session_id", "settings"]
