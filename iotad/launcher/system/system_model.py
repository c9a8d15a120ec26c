"""The model of a checked system: its nodes (each its declaration and the channel table of its
IOTA), concrete bindings and external inputs, and what a launcher asks of it (which nodes a host
runs, a node host's config); and how a node's IOTA is built in this process to read its channel
table. `system_file.py` makes one from a declaration, checking it; nothing here reads a file."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from iotad.node_host import wire
from iotad.kernel.ports import Port
from iotad.launcher.system.bus_logger import logger_port_config
from iotad.launcher.system.declaration import LOOPBACK_LISTEN, CanBusSpec, Declaration, HostSpec, NodeDecl
from iotad.launcher.system.link_watch import link_params


@dataclass
class ChannelInfo:
    """An external channel of a node's IOTA, as seen from outside the node."""

    name: str
    direction: str
    type: Any
    switching_time: float
    size: int | None  # None: one channel; else a family of `size` members

    def members(self) -> list[int | None]:
        return [None] if self.size is None else list(range(self.size))


@dataclass
class NodeSpec:
    """A node of a checked system: its declaration (`NodeDecl`, whose fields it shows, read-only)
    and the channel table of its IOTA (empty when the system was loaded unchecked)."""

    declared: NodeDecl
    channels: dict[str, ChannelInfo] = field(default_factory=dict)
    param_names: frozenset[str] = frozenset()  # its IOTA's parameters (empty when loaded unchecked)

    # ------------------------------------------------------------ as declared (NodeDecl)
    @property
    def name(self) -> str:
        return self.declared.name

    @property
    def entry(self) -> str:
        return self.declared.entry

    @property
    def source(self) -> dict[str, Any]:
        return self.declared.source

    @property
    def params(self) -> dict[str, Any]:
        return self.declared.params

    @property
    def restart(self) -> str:
        return self.declared.restart

    @property
    def max_restarts(self) -> int:
        return self.declared.max_restarts

    @property
    def backoff(self) -> float:
        return self.declared.backoff

    @property
    def host(self) -> str | None:
        return self.declared.host

    @property
    def after(self) -> list[str]:
        return self.declared.after

    @property
    def policy(self) -> str | None:
        return self.declared.policy

    @property
    def seed(self) -> int | None:
        return self.declared.seed

    @property
    def required(self) -> bool:
        return self.declared.required

    @property
    def input_queue(self) -> int | None:
        return self.declared.input_queue

    @property
    def bus_logger(self) -> bool:
        return self.declared.bus_logger


@dataclass
class Binding:
    source: Port
    target: Port
    entry: str


@dataclass
class System:
    """A system file, parsed (`declaration`, whose settings, hosts and buses it shows, read-only)
    and, when loaded checked, checked: channel tables, concrete bindings, external inputs."""

    declaration: Declaration
    nodes: dict[str, NodeSpec] = field(default_factory=dict)
    bindings: list[Binding] = field(default_factory=list)  # concrete: one per (source, target) member
    external: set[Port] = field(default_factory=set)
    # [system.debug] allow_pub: inputs `iotad pub` may write into under access control
    allow_pub: set[Port] = field(default_factory=set)

    # ------------------------------------------------------------ as declared (Declaration)
    @property
    def name(self) -> str:
        return self.declaration.name

    @property
    def path(self) -> Path:
        return self.declaration.path

    @property
    def text(self) -> str:
        return self.declaration.text

    @property
    def errors(self) -> tuple[str, ...]:
        return self.declaration.errors

    @property
    def time_unit(self) -> float:
        return self.declaration.time_unit

    @property
    def listen(self) -> list[str]:
        return self.declaration.listen

    @property
    def connect(self) -> list[str]:
        return self.declaration.connect

    @property
    def hub_host(self) -> str | None:
        return self.declaration.hub_host

    @property
    def heartbeat_period(self) -> float:
        return self.declaration.heartbeat_period

    @property
    def heartbeat_timeout(self) -> float:
        return self.declaration.heartbeat_timeout

    @property
    def start_timeout(self) -> float:
        return self.declaration.start_timeout

    @property
    def clock_bound(self) -> float:
        return self.declaration.clock_bound

    @property
    def clock_period(self) -> float:
        return self.declaration.clock_period

    @property
    def link_timeout(self) -> float:
        return self.declaration.link_timeout

    @property
    def deadline_tolerance(self) -> float:
        return self.declaration.deadline_tolerance

    @property
    def arrival_tolerance(self) -> float:
        return self.declaration.arrival_tolerance

    @property
    def input_queue(self) -> int:
        return self.declaration.input_queue

    @property
    def start_gate(self) -> bool:
        return self.declaration.start_gate

    @property
    def strict(self) -> bool:
        return self.declaration.strict

    @property
    def goals(self) -> tuple:
        return self.declaration.goals

    @property
    def goals_until(self) -> float | None:
        return self.declaration.goals_until

    @property
    def hosts(self) -> Mapping[str, HostSpec]:
        return self.declaration.hosts

    @property
    def buses(self) -> Mapping[str, CanBusSpec]:
        return self.declaration.buses

    @property
    def sweep_metrics(self) -> str | None:
        return self.declaration.sweep_metrics

    @property
    def file(self) -> str:
        return self.declaration.file

    @property
    def file_nodes(self) -> list[str]:
        return self.declaration.file_nodes

    def bus_of(self, node: str) -> CanBusSpec | None:
        """The CAN bus `node` is a station of, if any."""
        return self.declaration.bus_of(node)

    def hub(self) -> list[str]:
        """Where `iotad run` opens this system's hub, as a client reaches it."""
        return self.declaration.hub()

    # ------------------------------------------------------------ what the launcher needs
    def nodes_on(self, host: str | None) -> list[NodeSpec]:
        """The nodes a launcher for `host` runs (all of them when `host` is None), in file order."""
        return [n for n in self.nodes.values() if host is None or n.host == host]

    def hosts_keeping_traces(self) -> list[str]:
        """The hosts whose nodes' traces stay home (`[hosts.NAME] traces = "home"`): their own
        recording holds them, and the hub hears their outputs but not their traces."""
        return [name for name, spec in self.hosts.items() if spec.traces == "home"]

    def nodes_traced_at(self, host: str | None) -> list[NodeSpec]:
        """The nodes whose traces the launcher for `host` subscribes to, for its summary and its
        recorder: at the hub every node but those of hosts that keep their traces home; on
        another host its own."""
        if not self.opens_hub(host):
            return self.nodes_on(host)
        home = set(self.hosts_keeping_traces())
        return [n for n in self.nodes.values() if n.host not in home]

    def opens_hub(self, host: str | None) -> bool:
        """Whether the launcher for `host` listens on the hub endpoints (else it connects to them)."""
        return host is None or host == self.hub_host

    def listen_for(self, host: str | None) -> list[str]:
        if host is not None and host in self.hosts:
            return list(self.hosts[host].listen)
        return list(LOOPBACK_LISTEN)

    def inputs_of(self, node: str) -> dict[str, list[str]]:
        """The node host's `inputs`: "channel" or "channel/index" -> keys of the bound outputs."""
        inputs: dict[str, list[str]] = {}
        for binding in self.bindings:
            if binding.target.node != node:
                continue
            target, source = binding.target, binding.source
            name = target.channel if target.index is None else f"{target.channel}/{target.index}"
            inputs.setdefault(name, []).append(
                wire.channel_key(self.name, source.node, source.channel, source.index))
        return inputs

    def readers_of(self, node: str) -> dict[str, list[str]]:
        """The node host's `readers`: "channel" or "channel/index" of an output -> the nodes bound
        to read it (for restart notices: a reader's restart may have lost what it was sent)."""
        readers: dict[str, list[str]] = {}
        for binding in self.bindings:
            if binding.source.node != node:
                continue
            source = binding.source
            name = source.channel if source.index is None else f"{source.channel}/{source.index}"
            nodes = readers.setdefault(name, [])
            if binding.target.node not in nodes:
                nodes.append(binding.target.node)
        return readers

    def node_config(self, node: str, origin: float, hub: list[str]) -> dict[str, Any]:
        """The JSON config of `python -m iotad.node_host` (docs/internals.md, "Node host")."""
        spec = self.nodes[node]
        config = {"system": self.name, "path": spec.name, "source": dict(spec.source),
                  "params": {**link_params(self, node), **spec.params},
                  "time_unit": self.time_unit, "origin": origin, "listen": self.listen_for(spec.host),
                  "connect": list(hub), "inputs": self.inputs_of(node), "readers": self.readers_of(node),
                  "heartbeat_period": self.heartbeat_period,
                  "deadline_tolerance": self.deadline_tolerance, "arrival_tolerance": self.arrival_tolerance,
                  "input_queue": spec.input_queue if spec.input_queue is not None else self.input_queue}
        bus = self.bus_of(node)
        if bus is not None:
            config["can"] = bus.port_config()
        elif node in self.buses:  # the bus's own logger (bus_logger.py)
            config["can"] = logger_port_config(self.buses[node])
        if spec.policy is not None:
            config["policy"] = spec.policy
        if spec.seed is not None:
            config["seed"] = spec.seed
        if spec.host is not None:
            config["host"] = spec.host
        return config

    def receivers_of(self, source: Port) -> list[Port]:
        return [b.target for b in self.bindings if b.source == source]


# ---------------------------------------------------------------------------- IOTAs

def instantiate(node: NodeSpec) -> Any:
    """The node's IOTA, built in this process the way its node host will build it."""
    leaf_name = node.name.rsplit("/", 1)[-1]
    if node.source["kind"] == "esprit":
        from iotad.esprit import load_iota
        return load_iota(node.source["file"], iota=node.source.get("iota"), name=leaf_name, **node.params)
    from iotad.kernel.python_loader import iota_factory
    factory = iota_factory(node.source["ref"])
    return factory(leaf_name, **node.params)


def channel_table(instance: Any) -> dict[str, ChannelInfo]:
    """External channels of a leaf instance or a composite, with their concrete sizes."""
    from iotad.kernel.compose import Composite, flatten, leaf_channel
    from iotad.kernel.model import param_values

    table: dict[str, ChannelInfo] = {}
    if isinstance(instance, Composite):
        flat = flatten(instance)
        for name, (direction, endpoint) in flat.external.items():
            leaf, channel = leaf_channel(flat, endpoint)
            size = leaf.sizes[endpoint.channel] if endpoint.index is None else None
            table[name] = ChannelInfo(name, direction, channel.type, leaf.switching[endpoint.channel], size)
        return table
    spec = instance.iota_spec
    params = param_values(instance)
    for name, channel in spec.channels.items():
        if channel.external:
            # switching times may name a parameter: the table holds this instance's numbers
            table[name] = ChannelInfo(name, channel.direction, channel.type, spec.switching_of(channel, params),
                                      spec.size_of(channel, params))
    return table


def param_names(instance: Any) -> frozenset[str]:
    """The parameters a leaf IOTA declares (a composite's own: none)."""
    from iotad.kernel.compose import Composite
    from iotad.kernel.model import param_values
    return frozenset() if isinstance(instance, Composite) else frozenset(param_values(instance))
