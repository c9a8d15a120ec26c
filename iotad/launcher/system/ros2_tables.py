"""`[[ros2]]` tables: channels mapped to ROS 2 topics, and the implicit bridge node that carries
them (`iotad.ros2.bridge`, named `ros2`), bound to the mapped channels (docs/ros2.md)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from iotad.kernel.ports import Port
from iotad.launcher.system.declaration import NodeDecl, Ros2Decl
from iotad.launcher.system.system_model import Binding, NodeSpec, channel_table, instantiate
from iotad.ros2 import robot_description
from iotad.ros2.bridge import NODE_NAME, channel_names
from iotad.ros2.mapping import MappingError, parse

BRIDGE_REF = "iotad.ros2.bridge:ros2_bridge"
LAG = 0.05  # seconds the bridge may hold a ROS 2 message before forwarding it is late (a deadline miss)


def add_ros2_bridge(parser: Any, system: Any, tables: list[Ros2Decl]) -> None:
    """Check every `[[ros2]]` table of a system whose channels are known; where all are good and
    there is one at least, add the bridge node and its bindings. Problems go to `parser.error`."""
    if not tables:
        return
    if NODE_NAME in system.nodes:
        parser.error(system.nodes[NODE_NAME].entry, f"the name {NODE_NAME!r} is the ROS 2 bridge's when the "
                                                    f"file has [[ros2]] tables: rename this node")
        return
    bound = {b.target: b for b in system.bindings}
    mappings, switching, pairs = [], [], []
    for table in tables:
        entry, direction = table.entry, table.direction
        if robot_description.is_robot_description(dict(table.table)):  # the system's robot model: no channel
            try:
                mappings.append(robot_description.parse(dict(table.table), entry, _folder_of(parser)).plain())
            except MappingError as exc:
                parser.errors.append(f"{parser.file}: {exc}")
                continue
            switching.append(0.0)
            continue
        want = "input" if direction == "in" else "output"
        resolved = parser.resolve(system, table.channel, entry, want)
        if resolved is None:
            continue
        port, channel = resolved
        if channel.size is not None and port.index is None:
            parser.error(entry, f"{port} is a family of {channel.size}: map one member, e.g. {port}[0]")
            continue
        if direction == "in" and port in bound:
            parser.error(entry, f"{port} is already bound ({bound[port].entry}): a ROS 2 topic needs an input "
                                f"of its own")
            continue
        try:
            mapping = parse(dict(table.table), channel.type, entry)
        except MappingError as exc:
            parser.errors.append(f"{parser.file}: {exc}")
            continue
        pairs.append((len(mappings), port, direction, entry))
        mappings.append(mapping.plain())
        switching.append(channel.switching_time if direction == "in" else 0.0)
    if len(mappings) != len(tables):
        return
    node = NodeSpec(NodeDecl(name=NODE_NAME, entry="the ROS 2 bridge ([[ros2]])",
                             source={"kind": "python", "ref": BRIDGE_REF},
                             params={"mappings": mappings, "switching": switching, "ros_node": f"iotad_{system.name}",
                                     "lag": LAG / system.time_unit}))
    node.channels = channel_table(instantiate(node))
    system.nodes[NODE_NAME] = node
    for number, port, direction, entry in pairs:
        if direction == "out":
            system.bindings.append(Binding(port, Port(NODE_NAME, channel_names(number, "out")[0]), entry))
        else:
            inbound, forward = channel_names(number, "in")
            system.bindings.append(Binding(Port(NODE_NAME, forward), port, entry))
            system.external.add(Port(NODE_NAME, inbound))  # fed from outside: ROS 2, by the bridge's port


def _folder_of(parser: Any) -> Path | None:
    """The folder of the system file (where a robot_description's URDF is looked for first); None
    for a recorded copy, which has none."""
    path = getattr(getattr(parser, "declaration", None), "path", None)
    return path.parent if isinstance(path, Path) and path.is_absolute() else None


def mappings_of(system: Any) -> list[dict]:
    """The plain mappings of a system's bridge (none without [[ros2]] tables)."""
    node = system.nodes.get(NODE_NAME)
    if node is None or node.source.get("ref") != BRIDGE_REF:
        return []
    return list(node.params["mappings"])


def widen_grant(system: Any, node: str, grant: Any) -> None:
    """Under access control, the bridge also publishes its out topics, subscribes to its in
    topics, answers for its latched topics and declares its rmw_zenoh liveliness tokens
    (`@ros2_lv/<domain>/...`): `iotad.ros2.rights.bridge_rights`."""
    from iotad.ros2.mapping import Mapping
    from iotad.ros2.rights import bridge_rights

    if node != NODE_NAME:
        return
    rights = bridge_rights([Mapping.from_plain(plain) for plain in mappings_of(system)])
    for name in ("publish", "subscribe", "serve", "ask", "tokens", "watch"):
        getattr(grant, name).extend(key for key in getattr(rights, name) if key not in getattr(grant, name))
