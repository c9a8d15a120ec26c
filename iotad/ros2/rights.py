"""What each side of a ROS 2 link may do on the hub under access control, from the `[[ros2]]`
mappings alone: the bridge (iotad's node `ros2`) and a ROS 2 peer (`iotad certs ros2 NAME`).

Both speak rmw_zenoh (docs/ros2.md): data on `<domain>/<topic>/<type>/<hash>`, the graph as
liveliness tokens under `@ros2_lv/<domain>/`, and a transient-local topic's publication cache as a
queryable on `<session id>/<data key>` that a subscriber asks as `*/<data key>` (or with the
publisher's session id), accepting replies on the data key. The sets are what the hub's rules
(`iotad.launcher.access.access_policy.Grant`) take: key expressions per kind of message.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from iotad.ros2 import rmw_zenoh
from iotad.ros2.mapping import Mapping


@dataclass
class Rights:
    publish: list[str] = field(default_factory=list)     # puts
    subscribe: list[str] = field(default_factory=list)   # subscribers, and the puts sent to them
    serve: list[str] = field(default_factory=list)       # queryables, and the replies they send
    ask: list[str] = field(default_factory=list)         # queries, and the replies they get
    tokens: list[str] = field(default_factory=list)      # liveliness tokens declared
    watch: list[str] = field(default_factory=list)       # liveliness subscribed to or asked


def graph_keys(domains: set[int]) -> list[str]:
    """The ROS 2 graph of each domain: every entity's token lies under `@ros2_lv/<domain>/`."""
    return [f"{rmw_zenoh.ADMIN_SPACE}/{domain}/**" for domain in sorted(domains)]


def bridge_rights(mappings: list[Mapping]) -> Rights:
    """The bridge: publish its out topics (and answer for the latched ones from their caches),
    subscribe to its in topics (and ask the latched ones' caches), declare its own tokens."""
    rights = Rights()
    for mapping in mappings:
        latched = mapping.durability == "transient_local"
        if mapping.direction == "out":
            rights.publish.append(mapping.key)
            if latched:  # its caches' queryables (both kinds), the replies it sends on the data key,
                # and its advanced publisher's token and watch of advanced subscribers
                advanced = rmw_zenoh.advanced_keys(mapping.key)
                rights.serve += [rmw_zenoh.cache_query_key(mapping.key), mapping.key, advanced]
                rights.tokens.append(advanced)
                rights.watch.append(advanced)
        else:
            rights.subscribe.append(mapping.key)
            if latched:
                rights.ask += [rmw_zenoh.cache_query_key(mapping.key), mapping.key]
    rights.tokens = [*rights.tokens, *graph_keys({m.domain for m in mappings})]
    return rights


def peer_rights(mappings: list[Mapping]) -> Rights:
    """A ROS 2 peer: subscribe to the out topics (asking the latched ones' caches as rmw_zenoh's
    transient-local subscription does), publish on the in topics, and take part in the graph of the
    mappings' domains (declare its tokens, watch and ask the others'). Nothing else: no `iota/...`
    key, no other topic, no put on an out topic."""
    rights, advanced = Rights(), []
    for mapping in mappings:
        if mapping.direction == "out":
            rights.subscribe.append(mapping.key)
            # asked whatever its durability: a transient-local subscription asks every cache of
            # its topic, and a query that no queryable answers carries nothing
            rights.ask += [rmw_zenoh.cache_query_key(mapping.key), mapping.key]
            # a later rmw_zenoh's transient-local subscription is an advanced subscriber: it
            # declares its own token, watches the publishers', asks their caches and hears their
            # heartbeats
            advanced.append(rmw_zenoh.advanced_keys(mapping.key))
        else:
            rights.publish.append(mapping.key)
    graph = graph_keys({m.domain for m in mappings})
    rights.tokens, rights.watch = [*graph, *advanced], [*graph, *advanced]
    rights.ask += advanced
    rights.subscribe += advanced
    for name in ("publish", "subscribe", "ask"):
        setattr(rights, name, list(dict.fromkeys(getattr(rights, name))))
    return rights
