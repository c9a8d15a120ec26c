"""Composite IOTAs: components under instance paths, outputs bound to inputs, external channels.

    pair = Composite("pair", Ping("ping"), Pong("pong"),
                     bind=[("ping.out", "pong.inp"), ("pong.out", "ping.inp")],
                     outputs={"served": "pong.out"})

An endpoint is "child.channel" or "child.channel[3]"; a child may itself be a composite, so
paths nest (`buggy/conscious/wander`). `inputs`/`outputs` name the composite's external channels
and the component channel each one is; a composite may also have an `own` IOTA (state and
actions of its own, as an ESPRIT body with both), whose channels it names without a dot.
Families bind element-wise when neither side names an index.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable

from iotad.kernel.model import Channel, SpecError, param_values
from iotad.kernel.ports import Port, PortSyntaxError


class Composite:
    def __init__(self, name: str, *components: Any, bind: Iterable[tuple[str, str]] = (),
                 inputs: dict[str, str] | None = None, outputs: dict[str, str] | None = None,
                 own: Any = None):
        self.instance_name = name
        self.components: dict[str, Any] = {}
        self.bindings: list[tuple[str, str]] = []
        self.inputs: dict[str, str] = dict(inputs or {})
        self.outputs: dict[str, str] = dict(outputs or {})
        self.own = own
        for component in components:
            self.add(component)
        for source, target in bind:
            self.bind(source, target)
        self.build()

    def build(self) -> None:
        """Subclasses may add components and bindings here."""

    def add(self, component: Any) -> Any:
        name = component.instance_name
        if "/" in name or "." in name or not name:
            raise SpecError(f"{self.instance_name}: component name {name!r} may not be empty or hold '/' or '.'")
        if name in self.components:
            raise SpecError(f"{self.instance_name}: two components named {name}")
        self.components[name] = component
        return component

    def bind(self, source: str, target: str) -> None:
        self.bindings.append((source, target))

    def __repr__(self) -> str:
        return f"<Composite {self.instance_name}: {', '.join(self.components)}>"


class Endpoint(Port):
    """A concrete channel of a leaf: its path (`node`), channel name and index (None: the whole family)."""

    __slots__ = ()

    @property
    def path(self) -> str:
        return self.node


@dataclass
class Leaf:
    path: str
    iota: Any  # an instance with `iota_spec`, params and state
    sizes: dict[str, int | None]
    switching: dict[str, float]  # switching times with parameters resolved


@dataclass
class Flat:
    """A system flattened for the engine: leaves in order, bindings between their channels,
    and the root's external channels mapped to leaf channels."""

    leaves: list[Leaf]
    bindings: list[tuple[Endpoint, Endpoint]]
    external: dict[str, tuple[str, Endpoint]]  # root channel -> (direction, leaf endpoint)


def _leaf_of(iota: Any, path: str) -> Leaf:
    spec = iota.iota_spec
    params = param_values(iota)
    sizes = {name: spec.size_of(ch, params) for name, ch in spec.channels.items()}
    switching = {name: spec.switching_of(ch, params) for name, ch in spec.channels.items()}
    return Leaf(path, iota, sizes, switching)


def flatten(root: Any) -> Flat:
    leaves: list[Leaf] = []
    bindings: list[tuple[Endpoint, Endpoint]] = []
    external = _flatten(root, root.instance_name, leaves, bindings)
    flat = Flat(leaves, bindings, external)
    _check_bindings(flat)
    return flat


def _parse(text: str, where: str) -> Port:
    """"child.channel[k]", or "channel[k]" for the composite's own (node "")."""
    try:
        return Port.parse(text, node_optional=True)
    except PortSyntaxError:
        raise SpecError(f"{where}: bad endpoint {text!r} (expected child.channel or child.channel[k])") from None


def _flatten(node: Any, path: str, leaves: list[Leaf], bindings: list) -> dict[str, tuple[str, Endpoint]]:
    """Adds node's leaves and bindings; returns node's external channels as leaf endpoints."""
    if not isinstance(node, Composite):
        leaf = _leaf_of(node, path)
        leaves.append(leaf)
        return {name: (ch.direction, Endpoint(path, name))
                for name, ch in node.iota_spec.channels.items() if ch.external}
    exposed: dict[str, dict[str, tuple[str, Endpoint]]] = {}
    own_channels: dict[str, tuple[str, Endpoint]] = {}
    if node.own is not None:
        own_channels = _flatten(node.own, path, leaves, bindings)
    for name, child in node.components.items():
        exposed[name] = _flatten(child, f"{path}/{name}", leaves, bindings)

    def resolve(text: str, want: str) -> Endpoint:
        where = f"{path}: {text}"
        port = _parse(text, where)
        child, channel, index = port.node, port.channel, port.index
        if child:
            if child not in exposed:
                raise SpecError(f"{where}: no component {child} (have {sorted(exposed)})")
            table = exposed[child]
        else:
            table = {**own_channels, **mapped}
        if channel not in table:
            raise SpecError(f"{where}: no external channel {channel} (have {sorted(table)})")
        direction, endpoint = table[channel]
        if want and direction != want:
            raise SpecError(f"{where}: is an {direction} channel, expected an {want}")
        if index is not None:
            if endpoint.index is not None:
                raise SpecError(f"{where}: {endpoint} is not a family")
            endpoint = Endpoint(endpoint.path, endpoint.channel, index)
        return endpoint

    mapped: dict[str, tuple[str, Endpoint]] = {}
    for name, target in node.inputs.items():
        mapped[name] = ("input", resolve(target, "input"))
    for name, target in node.outputs.items():
        mapped[name] = ("output", resolve(target, "output"))
    fed = set()
    for source, target in node.bindings:
        resolved = resolve(target, "input")
        bindings.append((resolve(source, "output"), resolved))
        fed.add(resolved)
    # an own input fed here by a component's output is not the composite's to expose: its parent
    # could bind it a second time, and a system would list it as an input nobody feeds
    own_channels = {name: (direction, endpoint) for name, (direction, endpoint) in own_channels.items()
                    if not (direction == "input" and endpoint in fed)}
    return {**own_channels, **mapped}


def leaf_channel(flat: Flat, endpoint: Endpoint) -> tuple[Leaf, Channel]:
    for leaf in flat.leaves:
        if leaf.path == endpoint.path:
            return leaf, leaf.iota.iota_spec.channels[endpoint.channel]
    raise SpecError(f"no IOTA at {endpoint.path}")


def expand(flat: Flat, source: Endpoint, target: Endpoint) -> list[tuple[Endpoint, Endpoint]]:
    """A binding as concrete (index-level) pairs; families of equal size bind element-wise."""
    src_leaf, _ = leaf_channel(flat, source)
    dst_leaf, _ = leaf_channel(flat, target)
    src_size = src_leaf.sizes[source.channel] if source.index is None else None
    dst_size = dst_leaf.sizes[target.channel] if target.index is None else None
    if src_size is None and dst_size is None:
        return [(source, target)]
    if src_size is not None and dst_size is not None:
        if src_size != dst_size:
            raise SpecError(f"binding {source} -> {target}: families of sizes {src_size} and {dst_size}")
        return [(Endpoint(source.path, source.channel, k), Endpoint(target.path, target.channel, k))
                for k in range(src_size)]
    raise SpecError(f"binding {source} -> {target}: a family binds to a family; name an index "
                    "to bind one member")


def _check_bindings(flat: Flat) -> None:
    seen: dict[Endpoint, Endpoint] = {}
    for source, target in flat.bindings:
        src_leaf, src_channel = leaf_channel(flat, source)
        dst_leaf, dst_channel = leaf_channel(flat, target)
        if (src_channel.type is None) != (dst_channel.type is None) or (
                src_channel.type is not None and src_channel.type.json_schema() != dst_channel.type.json_schema()):
            raise SpecError(f"binding {source} -> {target}: types differ "
                            f"({src_channel.type} vs {dst_channel.type})")
        for leaf, endpoint in ((src_leaf, source), (dst_leaf, target)):
            size = leaf.sizes[endpoint.channel]
            if endpoint.index is not None and (size is None or endpoint.index >= size):
                raise SpecError(f"binding {source} -> {target}: {endpoint} is out of range "
                                f"({endpoint.channel} has {size or 'no'} members)")
        for _, concrete_target in expand(flat, source, target):
            if concrete_target in seen:
                raise SpecError(f"input {concrete_target} is bound twice (from {seen[concrete_target]} "
                                f"and {source})")
            seen[concrete_target] = source
