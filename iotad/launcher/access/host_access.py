"""Access control across hosts: the users a system spread over hosts adds to the hub's policy
(each other host's launcher and agent, and the hub's side of the agents' wire), which users the
hub admits at all (`hub_policy`), and which credentials the hub hands each host's agent
(docs/hosts.md, "Access control").

The nodes keep exactly their one-machine rights (`access_policy.derive`), but only the hub
host's own nodes log in to the hub: another host's nodes log in to their host's router
(iotad/launcher/access/host_router.py), which makes their passwords itself, so the hub neither holds nor
hands out a password that would let one of them open a session with it directly.

A host's launcher may only do what a launcher that does not hold the hub does: publish its
events, follow the nodes' liveliness, heartbeats and traces, ask the hub's origin and clock, and
open its own start gate; and, as the router its host's nodes reach the hub through, what those
nodes may do.
A host's agent may only serve its own orders and publish its own lines: the hub's `iotad run`
asks `iota/@agent/<host>/run` with that host's credentials in the order, so no other user can
declare the queryable that receives them."""
from __future__ import annotations

import hashlib

from iotad.node_host import wire
from iotad.machine.agent_secret import agent_user
from iotad.machine.clock_offset import clock_key
from iotad.launcher.access.access_policy import Grant, Policy, derive, node_user
from iotad.launcher.fleet_wire import AGENT_PREFIX, CODE_PREFIX, FLEET_USER, agent_key, launcher_user
from iotad.launcher.system.system_file import System

def host_users(system: System, host: str) -> list[str]:
    """The users whose credentials `host`'s agent receives from the hub: its launcher's alone (its
    router makes its nodes' own: `routed_users`)."""
    return [launcher_user(host)]


def routed_users(system: System, host: str) -> list[str]:
    """The node users that log in to `host`'s router, never to the hub."""
    return [node_user(node.name) for node in system.nodes_on(host)]


def routed_hosts(system: System) -> list[str]:
    """The hosts of `system` besides the hub's that hold nodes: under access control each has a
    router of its own (iotad/launcher/access/host_router.py)."""
    return list(dict.fromkeys(node.host for node in system.nodes.values() if node.host and node.host != system.hub_host))


def zenoh_mode(system: System) -> str:
    """The zenoh mode of the hub's session and of every host's router under access control:
    "router" where two hosts or more besides the hub's each have a router, else "peer".

    Why: a zenoh peer relays between its clients and one peer, but not from one peer to another,
    and two hosts' routers cannot link to each other (each listens on a unix socket of its own
    machine), so with the hub and the routers peers what a node on arm sent reached the hub but
    never a node on base (measured with zenoh 1.10: 20 of 20 at the hub, none on base; the hub a
    router and the host routers peers: the same, since zenoh 1.9 dropped a router's brokering
    between peers). Routers route between routers (link state), so with all of them routers the
    node on base heard 20 of 20, and the hub still dropped what arm's launcher user may not publish.
    One host besides the hub's (or none) keeps the peer mode it has always run in."""
    return "router" if len(routed_hosts(system)) >= 2 else "peer"


def router_zid(password: str) -> str:
    """The zenoh id of a host's router, derived from its launcher user's password: the hub made that
    password and the host received it, so both know the id before the router links to the hub, and
    the hub can name the router's link in its own config (`across_hosts_settings`). The password is 24
    random bytes, so its hash tells nothing of it; zenoh wants lowercase hex without a leading 0."""
    digest = hashlib.sha256(b"iotad host router id\0" + password.encode()).hexdigest()[:32]
    return digest.lstrip("0") or "1"


def across_hosts_settings(zids: list[str] | None = None) -> dict:
    """zenoh settings for a session that forwards between hosts (the hub, a host's router): what it
    forwards toward another host goes with congestion control DROP and batched (not express), by
    zenoh's `qos/network` overwrite on egress, toward the routers `zids` (the hub's), or on every
    TLS link (a host's router, whose one TLS link is the hub's).

    Why DROP: zenoh keeps a message's congestion control on every hop, and the nodes publish with
    BLOCK so that their own host's recorder loses nothing. A router that forwards such a message to
    a host cut off from it pushes it onto that link's queue on the receive task of the link it came
    in on; once the queue was full (the cut link's socket buffer full behind it) the task waited,
    and every task behind it, until the lease closed the cut link: with three hosts the hub heard
    nothing from its own host's nodes nor from base for 10 s, killed its nodes as frozen, and
    brain and base stopped hearing each other (docs/hosts.md, section 8). Now such a message waits
    at most zenoh's `wait_before_drop` (1 ms) once, and what then finds the queue still full is
    dropped at once: what a host that cannot be reached would have lost anyway once the lease closed
    its links. What stays on one host, the recorder's traffic included, keeps BLOCK.

    Why batched: an express message takes a batch of its own, and a link's queue holds two a
    priority, so with DROP alone a hold of the hub (or of the machine) of about 90 ms, on this
    loaded 2-core machine, filled the queue toward base, both up, and 3 of brain's outputs to base
    were lost with three pulses at 50 a second. Batched, the same queue holds two 64 KB batches of
    messages, seconds of such traffic. zenoh sends a batch at once when its link is idle; it holds
    one back for more (up to 1 ms) only while the link is busy.

    None for a hub without other hosts."""
    if zids is not None and not zids:
        return {}
    item: dict = {"id": "across-hosts-drop", "messages": ["put", "delete", "query"], "flows": ["egress"],
                  "overwrite": {"congestion_control": "drop", "express": False}}
    item.update({"zids": list(zids)} if zids is not None else {"link_protocols": ["tls"]})
    return {"qos/network": [item]}


def hub_policy(system: System, hosts: list[str]) -> Policy:
    """What the hub admits: the nodes that reach it directly (the hub host's, or every node of a
    system on one machine), its recorder and tools, and for each other host of `hosts` its launcher
    and agent, and the hub's fleet session. Another host's nodes are absent: their launcher user
    holds their rights (`launcher_grant`), and the hub knows no password of theirs."""
    policy = derive(system)
    elsewhere = {user for host in hosts for user in routed_users(system, host)}
    policy.grants = [grant for grant in policy.grants if grant.user not in elsewhere]
    policy.grants += host_grants(system, hosts)
    return policy


def launcher_grant(system: System, host: str) -> Grant:
    """What `host`'s launcher user may do at the hub: its own part (its launcher events, the hub's
    origin on its clock that its nodes follow, its start gate, the nodes' liveliness, heartbeats
    and traces), and, since its session is the router its nodes reach the hub through
    (iotad/launcher/access/host_router.py), what each of those nodes may do, nothing more."""
    name = system.name
    grant = Grant(
        launcher_user(host), f"launcher of host {host}",
        publish=[wire.launcher_key(name), wire.host_origin_key(name, host)],
        subscribe=[wire.every_node(name, wire.HEARTBEAT), wire.every_node(name, wire.TRACE)],
        ask=[wire.origin_key(name), clock_key(name)],
        tokens=[wire.gate_key(name, host)],
        watch=[wire.every_node(name, wire.ALIVE)],
        # told of the hub's clock queryable: the host's launcher sends a query only toward the
        # queryables it knows of (measured with zenoh 1.10: without this no clock query of a host's
        # router reached a hub in router mode, `zenoh_mode`; nor a peer hub whose queryable was
        # declared after the router had linked)
        declarations=[clock_key(name)])
    own = set(routed_users(system, host))
    for node in derive(system).grants:
        if node.user in own:
            for part in ("publish", "subscribe", "serve", "ask", "tokens", "watch", "declarations"):
                keys = getattr(grant, part)
                keys.extend(key for key in getattr(node, part) if key not in keys)
    return grant


def host_grants(system: System, hosts: list[str]) -> list[Grant]:
    """The grants for the other hosts `hosts` of `system` and for the hub's fleet session."""
    grants = []
    for host in hosts:
        grants.append(launcher_grant(system, host))
        key = agent_key(host)
        grants.append(Grant(
            agent_user(host), f"agent of host {host}",
            publish=[f"{key}/log", f"{key}/exit"],
            serve=[f"{key}/run", f"{key}/stop", f"{key}/lines"],
            # an agent may measure the hub's clock itself before its launcher starts, and fetch
            # the files its order names by their hash (iotad/launcher/hosts/code_by_hash.py)
            ask=[clock_key("*"), f"{CODE_PREFIX}/*"],
            tokens=[key],
            declarations=[f"{AGENT_PREFIX}/*/log", f"{AGENT_PREFIX}/*/exit", f"{CODE_PREFIX}/*"]))
    if hosts:
        every = f"{AGENT_PREFIX}/*"
        grants.append(Grant(
            FLEET_USER, "the hub's side of the agents",
            subscribe=[f"{every}/log", f"{every}/exit"],
            ask=[f"{every}/run", f"{every}/stop", f"{every}/lines"],
            serve=[f"{CODE_PREFIX}/*"],  # the files the orders name, by hash
            watch=[every],
            declarations=[f"{every}/run", f"{every}/stop", f"{every}/lines", f"{CODE_PREFIX}/*"]))
    return grants


__all__ = ["FLEET_USER", "across_hosts_settings", "host_grants", "host_users", "hub_policy", "launcher_grant", "launcher_user",
           "routed_hosts", "routed_users", "router_zid", "zenoh_mode"]
