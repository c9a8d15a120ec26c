"""Who may write what, derived from a checked system: per node the key expressions it may
publish (its outputs, `@trace`, `@heartbeat`, its `@alive` token and `@spec` replies), query (the
`@spec` of the peers whose restarts it is told of, to tell a restart from a return) and
subscribe (the outputs bound to its inputs, and its own input keys), read access for the recorder
and the introspection tools, and write access for `iotad pub` only on the inputs named in
`[system.debug] allow_pub`. `Policy.acl()` turns it into zenoh's own `access_control`
configuration (default deny) for the hub; docs/access-control.md says what this protects
against and what it does not."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iotad.node_host import wire
from iotad.node_host.peer_restart import PEER_RESTART, told_of
from iotad.launcher.system.ros2_tables import widen_grant
from iotad.launcher.system.system_file import System

RECORDER_USER = "iotad-recorder"
TOOLS_USER = "iotad-tools"
# What readers (recorder, ls/echo/hz/top/view) may subscribe to and ask: every key of the hub.
# `**` does not match `@` chunks in zenoh, so each `@` key of iotad is named.
READ_KEYS = ["**", f"{wire.PREFIX}/**/{wire.TRACE}", f"{wire.PREFIX}/**/{wire.HEARTBEAT}", f"{wire.PREFIX}/*/{wire.LAUNCHER}"]
QUERY_KEYS = [f"{wire.PREFIX}/**/{wire.SPEC}", f"{wire.PREFIX}/*/{wire.ORIGIN}", "**"]
ALIVE_KEYS = [f"{wire.PREFIX}/**/{wire.ALIVE}"]
# Which subscribers and queryables exist is told to every user: a client's publisher sends only
# when it knows of a matching subscriber (zenoh's interests), and a declaration carries no data.
# The hub's origin on another host's clock, which that host's launcher publishes to its nodes
ORIGIN_KEYS = [f"{wire.PREFIX}/*/{wire.ORIGIN}/*"]
DECLARATION_KEYS = [*READ_KEYS, *QUERY_KEYS[:2], *ALIVE_KEYS, *ORIGIN_KEYS]


def node_user(path: str) -> str:
    return f"node-{path}"


@dataclass
class Grant:
    """What one authenticated user may do on the hub."""

    user: str
    role: str                                            # node, recorder, tools
    publish: list[str] = field(default_factory=list)     # put from it
    subscribe: list[str] = field(default_factory=list)   # subscribers it declares, puts sent to it
    serve: list[str] = field(default_factory=list)       # queryables it declares: queries to it, its replies
    ask: list[str] = field(default_factory=list)         # queries from it, replies to it
    tokens: list[str] = field(default_factory=list)      # liveliness tokens it declares
    watch: list[str] = field(default_factory=list)       # liveliness it subscribes to or asks
    # subscribers and queryables it is told of beyond every user's `DECLARATION_KEYS`: the agents'
    # wire (iotad/launcher/access/host_access.py) is outside `iota/<system>`
    declarations: list[str] = field(default_factory=list)


@dataclass
class Policy:
    system: str
    grants: list[Grant]

    def users(self) -> list[str]:
        return [g.user for g in self.grants]

    def grant(self, user: str) -> Grant:
        return next(g for g in self.grants if g.user == user)

    def acl(self) -> dict[str, Any]:
        """zenoh's `access_control` config: one subject and a few rules per user, default deny."""
        rules, subjects, policies = [], [], []
        for number, grant in enumerate(self.grants):
            ids = []

            def rule(suffix: str, flow: str, messages: list[str], keys: list[str]) -> None:
                if keys:
                    rule_id = f"u{number}-{suffix}"
                    rules.append({"id": rule_id, "permission": "allow", "flows": [flow],
                                  "messages": messages, "key_exprs": sorted(set(keys))})
                    ids.append(rule_id)

            rule("put", "ingress", ["put"], grant.publish)
            rule("sub", "ingress", ["declare_subscriber"], grant.subscribe)
            rule("recv", "egress", ["put"], grant.subscribe)
            rule("serve", "ingress", ["declare_queryable", "reply"], grant.serve)
            # a query reaches a queryable with the asker's key expression (`iota/S/**/@spec`)
            rule("query-in", "egress", ["query"], grant.serve and [*grant.serve, f"{wire.PREFIX}/**/{wire.SPEC}"])
            rule("ask", "ingress", ["query"], grant.ask)
            rule("answers", "egress", ["reply"], grant.ask)
            rule("token", "ingress", ["liveliness_token"], grant.tokens)
            rule("watch", "ingress", ["declare_liveliness_subscriber", "liveliness_query"], grant.watch)
            rule("seen", "egress", ["liveliness_token"], grant.watch)
            rule("declared", "egress", ["declare_subscriber", "declare_queryable"],
                 [*DECLARATION_KEYS, *grant.declarations])
            subject_id = f"s{number}"
            subjects.append({"id": subject_id, "usernames": [grant.user]})
            policies.append({"id": f"p{number}", "rules": ids, "subjects": [subject_id]})
        return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
                "policies": policies}

    def lines(self, enforcer: str = "the hub") -> list[str]:
        """The policy for a person (`iotad run --check`), as `enforcer` enforces it."""
        out = [f"access control of {self.system} (default: deny; {enforcer} enforces it):"]
        for grant in self.grants:
            out.append(f"  {grant.user} ({grant.role})")
            for label, keys in (("publish", grant.publish), ("subscribe", grant.subscribe),
                                ("answer queries on", grant.serve), ("query", grant.ask),
                                ("liveliness token", grant.tokens), ("watch liveliness", grant.watch)):
                if keys:
                    out.append(f"    {label + ':':<19} {', '.join(keys)}")
            if grant.user == TOOLS_USER and not grant.publish:
                out.append("    publish:            nothing ('iotad pub' needs [system.debug] allow_pub)")
        return out


def derive(system: System) -> Policy:
    """The policy of a checked system (`load_system(..., check=True)`: channel tables known)."""
    name = system.name
    grants = []
    for node in system.nodes.values():
        base = f"{wire.PREFIX}/{name}/{node.name}"
        grant = Grant(node_user(node.name), "node")
        own_inputs = []
        for channel in node.channels.values():
            keys = [wire.channel_key(name, node.name, channel.name, index) for index in channel.members()]
            (grant.publish if channel.direction == "output" else own_inputs).extend(keys)
        grant.publish += [f"{base}/{wire.TRACE}", f"{base}/{wire.HEARTBEAT}"]
        bound = [key for keys in system.inputs_of(node.name).values() for key in keys]
        grant.subscribe = _unique(bound + own_inputs)
        if node.host is not None and not system.opens_hub(node.host):
            # its launcher measures the host's clock during the run; the node's clock follows
            grant.subscribe.append(wire.host_origin_key(name, node.host))
        grant.serve = [f"{base}/{wire.SPEC}"]
        if PEER_RESTART in node.channels:
            # its host asks a peer whose token came back which process it is (a restart, or the
            # same one back after a cut past the lease): the @spec of those peers, no other's
            peers = told_of(name, node.name, system.inputs_of(node.name), system.readers_of(node.name),
                            node.channels[PEER_RESTART].type)
            grant.ask = [wire.node_key(name, peer, wire.SPEC) for peer in sorted(peers)]
        grant.tokens = [f"{base}/{wire.ALIVE}"]
        # peer_restart inputs watch the others' tokens; every node waits for its launcher's start gate
        grant.watch = [wire.every_node(name, wire.ALIVE), wire.gate_key(name, "*")]
        widen_grant(system, node.name, grant)  # the ROS 2 bridge's topics and tokens, if it is this node
        grants.append(grant)
    reader = dict(subscribe=list(READ_KEYS), ask=list(QUERY_KEYS), watch=list(ALIVE_KEYS))
    grants.append(Grant(RECORDER_USER, "recorder", **reader))
    tools = Grant(TOOLS_USER, "tools: ls, echo, hz, top, view, pub", **reader)
    tools.publish = [wire.channel_key(name, port.node, port.channel, port.index)
                     for port in sorted(getattr(system, "allow_pub", ()), key=str)]
    grants.append(tools)
    return Policy(name, grants)


def _unique(keys: list[str]) -> list[str]:
    return list(dict.fromkeys(keys))


__all__ = ["Grant", "Policy", "RECORDER_USER", "TOOLS_USER", "derive", "node_user"]
