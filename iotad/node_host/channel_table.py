"""The channel table of a node: which zenoh key each external channel (and family member) of the
root IOTA publishes on or listens to, and the description the `@spec` queryable hands out.

Kept free of zenoh so that it can be checked (and the config rejected) before any session opens.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iotad.node_host import wire
from iotad.kernel.compose import Flat
from iotad.node_host.node_config import ConfigError, NodeConfig


@dataclass
class OutputPort:
    """One output channel (one family member) of the node: the engine event it comes from
    (leaf path, leaf channel, index) and the key it is published on."""

    name: str
    index: int | None
    key: str
    source: tuple[str, str, int | None]


@dataclass
class InputPort:
    """One input channel (one family member): every key it listens to (its own key first, so that
    `iotad pub` can inject into it, then the outputs bound to it by the system file)."""

    name: str
    index: int | None
    keys: list[str] = field(default_factory=list)


@dataclass
class ChannelTable:
    outputs: list[OutputPort]
    inputs: list[InputPort]
    described: list[dict]  # for @spec: one entry per external channel


def build(config: NodeConfig, flat: Flat) -> ChannelTable:
    outputs: list[OutputPort] = []
    inputs: list[InputPort] = []
    described: list[dict] = []
    leaves = {leaf.path: leaf for leaf in flat.leaves}
    wanted = dict(config.inputs)
    for name, (direction, endpoint) in flat.external.items():
        leaf = leaves[endpoint.path]
        channel = leaf.iota.iota_spec.channels[endpoint.channel]
        size = leaf.sizes[endpoint.channel] if endpoint.index is None else None
        members = [None] if size is None else list(range(size))
        entry = {"name": name, "direction": direction,
                 "type": None if channel.type is None else repr(channel.type),
                 "type_name": None if channel.type is None else channel.type.name,
                 "schema": None if channel.type is None else channel.type.json_schema(),
                 "switching_time": leaf.switching[endpoint.channel], "size": size, "keys": [], "bound": {}}
        for index in members:
            key = wire.channel_key(config.system, config.path, name, index)
            entry["keys"].append(key)
            if direction == "output":
                leaf_index = endpoint.index if index is None else index
                outputs.append(OutputPort(name, index, key, (endpoint.path, endpoint.channel, leaf_index)))
                continue
            label = name if index is None else f"{name}/{index}"
            bound = wanted.pop(label, [])
            entry["bound"][label] = list(bound)
            inputs.append(InputPort(name, index, [key] + [k for k in bound if k != key]))
        described.append(entry)
    if wanted:
        have = [p.name if p.index is None else f"{p.name}/{p.index}" for p in inputs]
        raise ConfigError(f"inputs name unknown input channel(s) {sorted(wanted)}; "
                          f"{config.path} has {have or 'no inputs'}")
    return ChannelTable(outputs, inputs, described)


def plain_params(params: dict[str, Any]) -> dict[str, Any]:
    """Parameters as msgpack-able data (a Python default might be any object: show its repr)."""
    from iotad.kernel.types import to_plain

    out = {}
    for name, value in params.items():
        value = to_plain(value)
        try:
            wire.encode(value)
        except TypeError:
            value = repr(value)
        out[name] = value
    return out
