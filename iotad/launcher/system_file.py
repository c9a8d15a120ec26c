"""System files: which IOTAs run as which processes, how their channels are bound, and where
the hub is. Parsed with tomllib and checked whole before anything starts.

    [system]
    name = "figure2"
    time_unit = 1.0                      # seconds per spec time unit, for every node
    [system.endpoints]
    listen = ["tcp/127.0.0.1:7447"]      # the launcher's hub; nodes connect to it
    connect = []                         # where the hub itself connects (another hub, a router)

    [[node]]
    name = "scheduler"                   # instance path, also its key: iota/figure2/scheduler/...
    spec = "../nodes/scheduler/scheduler.iota"   # or python = "scheduler.py:Scheduler"
    params = { N = 2, T = 0.5 }
    restart = "on-failure"               # never | on-failure | always
    max_restarts = 5
    backoff = 0.1                        # seconds before the first restart, doubling after
    required = false                     # true: when it fails for good, stop the whole system
    input_queue = 1000                   # inputs waiting for the engine before more are dropped

    [[bind]]
    from = "vision.req"
    to = "scheduler.req[0]"

    external = ["scheduler.req[1]"]      # inputs fed from outside (iotad pub, another system)

    [[can]]                              # a CAN bus and the nodes on it (docs/system-file.md)
    name = "arm_bus"
    interface = "socketcan"              # python-can interface for real time: socketcan | udp_multicast
    channel = "vcan0"
    bitrate = 1000000                    # the bus model of `iotad run --virtual` uses it too
    stations = ["motor", "sim"]          # each has can_tx (output) and can_rx (input) of type canFrame

Checking instantiates every node's IOTA in this process (no zenoh, nothing started) to read its
channel table, then checks every binding (types, switching times, indices) and that every input
is bound or external (or fed by the node host: `can_rx` on a bus, `peer_restart`). Errors name the file and the entry and are collected, so that one run of
`iotad run --check` lists them all.
"""
from __future__ import annotations

import math
import re
import sys
import threading
import tomllib
from contextlib import contextmanager
from dataclasses import dataclass, field
from graphlib import CycleError, TopologicalSorter
from pathlib import Path
from typing import Any

from iotad.host import wire
from iotad.host.transport import DEFAULT_HUB_ENDPOINT, endpoint_problem
from iotad.kernel.text_file import read_text_file
from iotad.kernel.types import HUGE_INT

RESTART_MODES = ("never", "on-failure", "always")
LOOPBACK_LISTEN = ["tcp/127.0.0.1:0"]
_PATH = re.compile(r"^[A-Za-z_][\w-]*(/[A-Za-z_][\w-]*)*$")
_SYSTEM_NAME = re.compile(r"^[A-Za-z_][\w-]*$")
_ENDPOINT = re.compile(r"^\s*([A-Za-z_][\w/-]*)\.([A-Za-z_]\w*)(?:\[(\d+)\])?\s*$")

_SYSTEM_KEYS = {"name", "time_unit", "endpoints", "hub_host", "heartbeat_period", "heartbeat_timeout",
                "start_timeout", "external", "deadline_tolerance", "arrival_tolerance", "input_queue", "debug",
                "start_gate"}
# In TOML a key written after a [[node]] or [[bind]] table belongs to that table.
_TABLE_HINT = {"external": " (a top-level key must come before the first table; or put it in [system])"}
_NODE_KEYS = {"name", "spec", "iota", "python", "params", "restart", "max_restarts", "backoff", "host",
              "after", "policy", "seed", "required", "input_queue"}
_TOP_KEYS = {"system", "node", "bind", "external", "hosts", "can", "ros2", "sweep"}
_SWEEP_KEYS = {"metrics"}
_CAN_KEYS = {"name", "interface", "channel", "bitrate", "stations", "options", "log"}
CAN_TX, CAN_RX = "can_tx", "can_rx"  # the two channels of a node on a CAN bus
PEER_RESTART = "peer_restart"  # an input the node host feeds when a peer restarts (iotad.host.peer_restart)
DEFAULT_INPUT_QUEUE = 1000     # inputs a node host holds for its engine before it drops (and counts) more


class SystemFileError(Exception):
    """A system file that cannot run. `errors` holds one line per problem, each naming the entry."""

    def __init__(self, errors: list[str]):
        super().__init__("\n".join(errors))
        self.errors = errors


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
    name: str
    entry: str                       # how messages name it: '[[node]] #1 (name="scheduler")'
    source: dict[str, Any]           # the node host's "source": esprit file or python ref, absolute
    params: dict[str, Any] = field(default_factory=dict)
    restart: str = "on-failure"
    max_restarts: int = 5
    backoff: float = 0.1
    host: str | None = None
    after: list[str] = field(default_factory=list)
    policy: str | None = None
    seed: int | None = None
    required: bool = False           # when it ends for good, the launcher stops the whole system
    input_queue: int | None = None   # None: the [system] value
    channels: dict[str, ChannelInfo] = field(default_factory=dict)


@dataclass(frozen=True)
class Port:
    """One concrete channel: node path, channel, index (None for a plain channel)."""

    node: str
    channel: str
    index: int | None = None

    def __str__(self) -> str:
        return f"{self.node}.{self.channel}" + ("" if self.index is None else f"[{self.index}]")


@dataclass
class Binding:
    source: Port
    target: Port
    entry: str


@dataclass
class CanBusSpec:
    """One `[[can]]` bus: how a real-time node reaches it (python-can) and which nodes sit on it."""

    name: str
    interface: str
    channel: str | None = None
    bitrate: int = 1_000_000
    stations: list[str] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)
    entry: str = ""
    log: bool = True  # real time: a bus logger node named after the bus (iotad/launcher/bus_logger.py)

    def port_config(self) -> dict[str, Any]:
        """The node host's `can` config (docs/internals.md): what it opens with python-can."""
        from iotad.launcher.can_env import resolved
        interface, channel = resolved(self.interface, self.channel)  # interface = "env": the environment's
        return {"bus": self.name, "interface": interface, "channel": channel,
                "bitrate": self.bitrate, "options": dict(self.options)}


@dataclass
class HostSpec:
    name: str
    listen: list[str] = field(default_factory=lambda: list(LOOPBACK_LISTEN))


@dataclass
class System:
    name: str
    path: Path
    time_unit: float = 1.0
    listen: list[str] = field(default_factory=lambda: [DEFAULT_HUB_ENDPOINT])
    connect: list[str] = field(default_factory=list)
    hub_host: str | None = None
    heartbeat_period: float = 0.2
    heartbeat_timeout: float = 3.0
    start_timeout: float = 15.0
    deadline_tolerance: float = 0.002  # seconds a firing may be late before it is a deadline miss
    arrival_tolerance: float = 0.002   # seconds an input may be early (jitter) against its switching time
    input_queue: int = DEFAULT_INPUT_QUEUE  # per node host, unless its [[node]] says otherwise
    # real time: the engines start together once every node is live (false: each as soon as its
    # own node is live, as `after` orders them; docs/internals.md "Start gate")
    start_gate: bool = True
    nodes: dict[str, NodeSpec] = field(default_factory=dict)
    bindings: list[Binding] = field(default_factory=list)  # concrete: one per (source, target) member
    external: set[Port] = field(default_factory=set)
    hosts: dict[str, HostSpec] = field(default_factory=dict)
    buses: dict[str, CanBusSpec] = field(default_factory=dict)
    # [system.debug] allow_pub: inputs `iotad pub` may write into under access control
    allow_pub: set[Port] = field(default_factory=set)
    # [sweep] metrics: "file.py:function" (absolute) or "module:function", read by `iotad sweep`
    sweep_metrics: str | None = None

    def bus_of(self, node: str) -> CanBusSpec | None:
        """The CAN bus `node` is a station of, if any."""
        return next((bus for bus in self.buses.values() if node in bus.stations), None)

    @property
    def file(self) -> str:
        return self.path.name

    # ------------------------------------------------------------ what the launcher needs
    def nodes_on(self, host: str | None) -> list[NodeSpec]:
        """The nodes a launcher for `host` runs (all of them when `host` is None), in file order."""
        return [n for n in self.nodes.values() if host is None or n.host == host]

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
        """The JSON config of `python -m iotad.host` (docs/internals.md, "Node host")."""
        spec = self.nodes[node]
        config = {"system": self.name, "path": spec.name, "source": spec.source, "params": spec.params,
                  "time_unit": self.time_unit, "origin": origin, "listen": self.listen_for(spec.host),
                  "connect": list(hub), "inputs": self.inputs_of(node), "readers": self.readers_of(node),
                  "heartbeat_period": self.heartbeat_period,
                  "deadline_tolerance": self.deadline_tolerance, "arrival_tolerance": self.arrival_tolerance,
                  "input_queue": spec.input_queue if spec.input_queue is not None else self.input_queue}
        bus = self.bus_of(node)
        if bus is not None:
            config["can"] = bus.port_config()
        elif node in self.buses:  # the bus's own logger (bus_logger.py)
            from iotad.launcher.bus_logger import logger_port_config
            config["can"] = logger_port_config(self.buses[node])
        if spec.policy is not None:
            config["policy"] = spec.policy
        if spec.seed is not None:
            config["seed"] = spec.seed
        return config

    def receivers_of(self, source: Port) -> list[Port]:
        return [b.target for b in self.bindings if b.source == source]


# ---------------------------------------------------------------------------- loading

def load_system(path: str | Path, check: bool = True) -> System:
    """Parse (and by default check) a system file; raises `SystemFileError` listing every problem."""
    path = Path(path)
    try:
        data = tomllib.loads(read_text_file(path))
    except OSError as exc:
        raise SystemFileError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    except tomllib.TOMLDecodeError as exc:
        bom = " (the file starts with a byte-order mark, which TOML does not allow: save it as UTF-8 without BOM)" \
            if path.read_bytes().startswith(b"\xef\xbb\xbf") else ""
        raise SystemFileError([f"{path.name}: not valid TOML: {exc}{bom}"]) from None
    except UnicodeDecodeError:
        raise SystemFileError([f"{path.name}: not UTF-8 text"]) from None
    except RecursionError:
        raise SystemFileError([f"{path.name}: a value is nested too deeply to read"]) from None
    except ValueError:  # tomllib reads no int of more than 4300 digits
        raise SystemFileError([f"{path.name}: an integer of thousands of digits, {HUGE_INT}"]) from None
    return _Parser(path, data).parse(check)


class _Parser:
    def __init__(self, path: Path, data: dict):
        self.path, self.data, self.errors = path.resolve(), data, []
        self.unbuilt: set[str] = set()  # nodes whose IOTA could not be made: their channels are unknown
        self.can_claims: dict[str, tuple[str, dict[int, str]]] = {}  # node -> its `can_node_ids()`
        self.base = self.path.parent
        self.file = path.name

    def error(self, entry: str, message: str) -> None:
        self.errors.append(f"{self.file}: {entry}: {message}")

    def parse(self, check: bool) -> System:
        for key in sorted(set(self.data) - _TOP_KEYS):
            self.error(key, f"unknown top-level key (expected one of {sorted(_TOP_KEYS)})")
        system = self.parse_system()
        self.parse_hosts(system)
        self.parse_nodes(system)
        self.parse_buses(system)
        self.parse_sweep(system)
        from iotad.launcher.bus_logger import add_bus_loggers
        add_bus_loggers(system)  # one implicit node per logged bus, named after it
        self.check_after(system)  # after the loggers: a node may start after a bus's logger
        if check and not self.errors:
            self.load_channels(system)
            self.check_stations(system)
        raw_binds = self.table_list("bind")
        raw_external = self.data.get("external", [])
        in_system = self.data.get("system", {}).get("external", []) if isinstance(self.data.get("system"), dict) else []
        if check and not self.errors:
            self.check_bindings(system, raw_binds)
            self.check_external(system, raw_external)
            if in_system:
                self.check_external(system, in_system, "[system] external")
            self.check_allow_pub(system)
            if not self.errors:  # [[ros2]]: the ROS 2 bridge node and its bindings (docs/ros2.md)
                from iotad.launcher.ros2_tables import add_ros2_bridge
                add_ros2_bridge(self, system, self.table_list("ros2"))
            if not self.errors:  # an input whose binding failed is not also "unbound"
                self.check_inputs_covered(system)
        if self.errors:
            raise SystemFileError(self.errors)
        return system

    # ------------------------------------------------------------ [system] and [hosts]
    def parse_system(self) -> System:
        raw = self.data.get("system", {})
        entry = "[system]"
        system = System(name=self.path.stem.replace(".", "_"), path=self.path)
        if not isinstance(raw, dict):
            self.error(entry, "must be a table")
            return system
        for key in sorted(set(raw) - _SYSTEM_KEYS):
            self.error(entry, f"unknown key {key!r} (expected one of {sorted(_SYSTEM_KEYS)})")
        if "name" in raw:
            if isinstance(raw["name"], str) and _SYSTEM_NAME.match(raw["name"]):
                system.name = raw["name"]
            else:
                self.error(entry, f"name must be one key chunk (letters, digits, _ and -), got {raw['name']!r}")
        elif not _SYSTEM_NAME.match(system.name):
            self.error(entry, f"no name given and the file name {system.name!r} is not a valid one")
        for key in ("time_unit", "heartbeat_period", "heartbeat_timeout", "start_timeout",
                    "deadline_tolerance", "arrival_tolerance"):
            if key in raw:
                value = raw[key]
                if key == "time_unit" and _positive(value) and value < 1e-6:
                    # recordings keep times in whole nanoseconds: finer spec units would merge events
                    self.error(entry, f"time_unit must be at least 1e-6 s (a microsecond), got {value!r}")
                elif _positive(value):
                    setattr(system, key, float(value))
                else:
                    self.error(entry, f"{key} must be a positive number of seconds, got {value!r}")
        if "start_gate" in raw:
            if isinstance(raw["start_gate"], bool):
                system.start_gate = raw["start_gate"]
            else:
                self.error(entry, f"start_gate must be true or false, got {raw['start_gate']!r}")
        if "input_queue" in raw:
            if _queue_size(raw["input_queue"]):
                system.input_queue = raw["input_queue"]
            else:
                self.error(entry, f"input_queue must be a whole number of inputs >= 1, got {raw['input_queue']!r}")
        if system.heartbeat_period >= system.heartbeat_timeout:
            self.error(entry, f"heartbeat_period ({system.heartbeat_period:g} s) must be below heartbeat_timeout "
                              f"({system.heartbeat_timeout:g} s), or every node is killed as frozen between "
                              "two of its heartbeats")
        endpoints = raw.get("endpoints", {})
        if not isinstance(endpoints, dict):
            self.error(entry, "endpoints must be a table: { listen = [...], connect = [...] }")
        else:
            for key in sorted(set(endpoints) - {"listen", "connect"}):
                self.error(entry, f"endpoints has unknown key {key!r} (expected listen, connect)")
            for key in ("listen", "connect"):
                if key in endpoints:
                    value = endpoints[key]
                    if isinstance(value, str):
                        value = [value]
                    problem = _endpoint_list_problem(value)
                    if problem:
                        self.error(entry, f"endpoints.{key}: {problem}")
                    else:
                        setattr(system, key, value)
            if not system.listen:
                self.error(entry, "endpoints.listen is empty: the hub must listen somewhere")
        if "hub_host" in raw:
            if isinstance(raw["hub_host"], str):
                system.hub_host = raw["hub_host"]
            else:
                self.error(entry, f"hub_host must be a host name, got {raw['hub_host']!r}")
        return system

    def parse_hosts(self, system: System) -> None:
        raw = self.data.get("hosts", {})
        if not isinstance(raw, dict):
            self.error("[hosts]", "must be a table of [hosts.NAME] tables")
            return
        for name, table in raw.items():
            entry = f"[hosts.{name}]"
            if not isinstance(table, dict):
                self.error(entry, "must be a table")
                continue
            for key in sorted(set(table) - {"listen"}):
                self.error(entry, f"unknown key {key!r} (expected listen)")
            host = HostSpec(name)
            if "listen" in table:
                value = [table["listen"]] if isinstance(table["listen"], str) else table["listen"]
                problem = _endpoint_list_problem(value) or ("" if value else "an empty list: it must listen somewhere")
                if problem:
                    self.error(entry, f"listen: {problem}")
                else:
                    host.listen = value
            system.hosts[name] = host

    # ------------------------------------------------------------ [[node]]
    def table_list(self, key: str) -> list:
        raw = self.data.get(key, [])
        if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
            self.error(f"[[{key}]]", f"must be an array of tables ([[{key}]] entries)")
            return []
        return raw

    def parse_nodes(self, system: System) -> None:
        raw_nodes = self.table_list("node")
        if not raw_nodes and "node" not in self.data:
            self.error("[[node]]", "the system has no nodes")
        for number, raw in enumerate(raw_nodes, 1):
            entry = f"[[node]] #{number}" + (f" (name={raw['name']!r})".replace("'", '"') if "name" in raw else "")
            node = self.parse_node(raw, entry, system)
            if node is None:
                continue
            if node.name in system.nodes:
                self.error(entry, f"a node named {node.name!r} is already {system.nodes[node.name].entry}")
                continue
            system.nodes[node.name] = node
        hosts_used = {n.host for n in system.nodes.values() if n.host is not None}
        if hosts_used and any(n.host is None for n in system.nodes.values()):
            self.error("[[node]]", "either every node names its host or none does")
        if system.hub_host is None and hosts_used:
            system.hub_host = next(n.host for n in system.nodes.values())
        if system.hub_host is not None and hosts_used and system.hub_host not in hosts_used | set(system.hosts):
            self.error("[system]", f"hub_host {system.hub_host!r} is not a host of any node")

    def parse_node(self, raw: dict, entry: str, system: System) -> NodeSpec | None:
        for key in sorted(set(raw) - _NODE_KEYS):
            self.error(entry, f"unknown key {key!r} (expected one of {sorted(_NODE_KEYS)})"
                              + _TABLE_HINT.get(key, ""))
        name = raw.get("name")
        if not isinstance(name, str) or not _PATH.match(name):
            self.error(entry, f"name must be an instance path such as \"vision\" or \"arm/wrist\", got {name!r}")
            return None
        if ("spec" in raw) == ("python" in raw):
            self.error(entry, "give exactly one of spec = \"file.iota\" or python = \"file.py:Class\"")
            return None
        if "spec" in raw:
            if not isinstance(raw["spec"], str):
                self.error(entry, f"spec must be a file name, got {raw['spec']!r}")
                return None
            file = (self.base / raw["spec"]).resolve()
            if not file.is_file():
                found = "is a folder; name the .iota file in it" if file.is_dir() else "not found"
                self.error(entry, f"spec file {raw['spec']!r} {found} (looked at {file})")
                return None
            if "iota" in raw and not isinstance(raw["iota"], str):
                self.error(entry, f"iota must be an IOTA name, got {raw['iota']!r}")
                return None
            source = {"kind": "esprit", "file": str(file), "iota": raw.get("iota")}
        else:
            if "iota" in raw:
                self.error(entry, "iota only goes with spec = \"file.iota\"; python names its class after ':'")
            ref = raw["python"]
            if not isinstance(ref, str) or ":" not in ref:
                self.error(entry, f"python must be \"file.py:Class\" or \"module:Class\", got {ref!r}")
                return None
            where, cls = ref.rsplit(":", 1)
            if where.endswith(".py"):
                file = (self.base / where).resolve()
                if not file.is_file():
                    found = "is a folder; name the .py file in it" if file.is_dir() else "not found"
                    self.error(entry, f"python file {where!r} {found} (looked at {file})")
                    return None
                ref = f"{file}:{cls}"
            source = {"kind": "python", "ref": ref}
        node = NodeSpec(name=name, entry=entry, source=source)
        params = raw.get("params", {})
        if not isinstance(params, dict):
            self.error(entry, "params must be a table, e.g. params = { N = 2 }")
        else:
            node.params = params
        restart = raw.get("restart", node.restart)
        if restart not in RESTART_MODES:
            self.error(entry, f"restart must be one of {', '.join(RESTART_MODES)}, got {restart!r}")
        node.restart = restart
        if "max_restarts" in raw:
            value = raw["max_restarts"]
            if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
                node.max_restarts = value
            else:
                self.error(entry, f"max_restarts must be a whole number >= 0, got {value!r}")
        if "backoff" in raw:
            if _positive(raw["backoff"]) or raw["backoff"] == 0:
                node.backoff = float(raw["backoff"])
            else:
                self.error(entry, f"backoff must be a number of seconds >= 0, got {raw['backoff']!r}")
        if "host" in raw:
            if isinstance(raw["host"], str) and _SYSTEM_NAME.match(raw["host"]):
                node.host = raw["host"]
            else:
                self.error(entry, f"host must be a host name, got {raw['host']!r}")
        after = raw.get("after", [])
        if isinstance(after, str):
            after = [after]
        if not isinstance(after, list) or not all(isinstance(a, str) for a in after):
            self.error(entry, f"after must be a list of node names, got {raw.get('after')!r}")
        else:
            node.after = after
        if "policy" in raw:
            if raw["policy"] in ("eager", "random"):
                node.policy = raw["policy"]
            else:
                self.error(entry, f"policy must be \"eager\" or \"random\", got {raw['policy']!r}")
        if "seed" in raw:
            if isinstance(raw["seed"], int) and not isinstance(raw["seed"], bool) and 0 <= raw["seed"] < 2**64:
                node.seed = raw["seed"]
            else:
                self.error(entry, f"seed must be a whole number from 0 to 2**64 - 1, got {raw['seed']!r}")
        if "required" in raw:
            if isinstance(raw["required"], bool):
                node.required = raw["required"]
            else:
                self.error(entry, f"required must be true or false, got {raw['required']!r}")
        if "input_queue" in raw:
            if _queue_size(raw["input_queue"]):
                node.input_queue = raw["input_queue"]
            else:
                self.error(entry, f"input_queue must be a whole number of inputs >= 1, got {raw['input_queue']!r}")
        return node

    def load_channels(self, system: System) -> None:
        for node in system.nodes.values():
            try:
                with _said_if_slow(f"still building node {node.name}'s IOTA to check it, after {SLOW_BUILD:g} s: "
                                   "its module or init may block (Ctrl-C stops)"):
                    instance = instantiate(node)
                node.channels = channel_table(instance)
                claims = getattr(instance, "can_node_ids", None)
                if callable(claims):
                    self.can_claims[node.name] = claims()
            except Exception as exc:  # noqa: BLE001 - whatever the spec raises is the user's message
                message = str(exc).strip() or type(exc).__name__
                if "\n" in message:  # an ESPRIT error: keep its caret picture, indented
                    first, rest = message.split("\n", 1)
                    message = first + "\n" + "\n".join("    " + line for line in rest.splitlines())
                self.error(node.entry, f"cannot instantiate its IOTA: {message}")
                self.unbuilt.add(node.name)  # one error, not one more per binding or bus it is in

    # ------------------------------------------------------------ [[bind]] and external
    def resolve(self, system: System, text: Any, entry: str, want: str) -> tuple[Port, ChannelInfo] | None:
        if not isinstance(text, str):
            self.error(entry, f"expected \"node.channel\" or \"node.channel[k]\", got {text!r}")
            return None
        match = _ENDPOINT.match(text)
        if not match:
            self.error(entry, f"{text!r} is not \"node.channel\" or \"node.channel[k]\"")
            return None
        node_name, channel_name, index = match.group(1), match.group(2), match.group(3)
        node = system.nodes.get(node_name)
        if node is None:
            self.error(entry, f"no node named {node_name!r} (nodes: {', '.join(system.nodes) or 'none'})")
            return None
        if node_name in self.unbuilt:
            return None
        channel = node.channels.get(channel_name)
        if channel is None:
            have = ", ".join(f"{c.name} ({c.direction})" for c in node.channels.values()) or "none"
            self.error(entry, f"node {node_name!r} has no external channel {channel_name!r} (it has {have})")
            return None
        if channel.direction != want:
            self.error(entry, f"{text} is an {channel.direction} channel; expected an {want}")
            return None
        port_index = None if index is None else int(index)
        if port_index is not None:
            if channel.size is None:
                self.error(entry, f"{node_name}.{channel_name} is not a family; drop the [{port_index}]")
                return None
            if port_index >= channel.size:
                members = f"{channel.size} members (0..{channel.size - 1})" if channel.size else \
                    "no members (its size parameter is 0)"
                self.error(entry, f"index {port_index} is out of range: {node_name}.{channel_name} has {members}")
                return None
        return Port(node_name, channel_name, port_index), channel

    def check_bindings(self, system: System, raw_binds: list[dict]) -> None:
        senders: dict[Port, list[Binding]] = {}
        for number, raw in enumerate(raw_binds, 1):
            entry = f"[[bind]] #{number}" + (f" (from={raw['from']!r})".replace("'", '"') if "from" in raw else "")
            for key in sorted(set(raw) - {"from", "to"}):
                self.error(entry, f"unknown key {key!r} (expected from, to)" + _TABLE_HINT.get(key, ""))
            if "from" not in raw or "to" not in raw:
                self.error(entry, "needs both from = \"node.output\" and to = \"node.input\"")
                continue
            source = self.resolve(system, raw["from"], entry, "output")
            target = self.resolve(system, raw["to"], entry, "input")
            if source is None or target is None:
                continue
            (src, src_channel), (dst, dst_channel) = source, target
            if not _same_type(src_channel.type, dst_channel.type):
                self.error(entry, f"types differ: {src} carries {_type_name(src_channel.type)}, "
                                  f"{dst} takes {_type_name(dst_channel.type)}")
                continue
            if src_channel.switching_time < dst_channel.switching_time:
                self.error(entry, f"{src} may send every {src_channel.switching_time:g} time units but {dst} "
                                  f"accepts one event per {dst_channel.switching_time:g}: the receiver "
                                  f"would reject inputs (switching time)")
                continue
            src_size = src_channel.size if src.index is None else None
            dst_size = dst_channel.size if dst.index is None else None
            if src_size is None and dst_size is None:
                pairs = [(src, dst)]
            elif src_size is not None and dst_size is not None:
                if src_size != dst_size:
                    self.error(entry, f"families of different sizes: {src} has {src_size} members, "
                                      f"{dst} has {dst_size}")
                    continue
                pairs = [(Port(src.node, src.channel, k), Port(dst.node, dst.channel, k)) for k in range(src_size)]
            else:
                family = src if src_size is not None else dst
                self.error(entry, f"{family} is a family of {src_size or dst_size}; bind it to a family "
                                  f"of the same size or name one member, e.g. {family}[0]")
                continue
            for pair_source, pair_target in pairs:
                binding = Binding(pair_source, pair_target, entry)
                system.bindings.append(binding)
                senders.setdefault(pair_target, []).append(binding)
        for target, bindings in senders.items():
            if len(bindings) < 2:
                continue
            switching = system.nodes[target.node].channels[target.channel].switching_time
            if switching > 0:
                names = ", ".join(f"{b.source} ({b.entry.split(' (')[0]})" for b in bindings)
                self.error(bindings[-1].entry, f"input {target} has {len(bindings)} senders ({names}); "
                                               f"together they can send closer than its switching time "
                                               f"{switching:g}, so the receiver would reject inputs")

    def check_external(self, system: System, raw: Any, where: str = "external") -> None:
        if not isinstance(raw, list):
            self.error(where, "must be a list such as [\"scheduler.req[1]\"]")
            return
        for number, text in enumerate(raw):
            entry = f"{where}[{number}]" + (f" ({text!r})".replace("'", '"') if isinstance(text, str) else "")
            resolved = self.resolve(system, text, entry, "input")
            if resolved is None:
                continue
            port, channel = resolved
            members = [port.index] if port.index is not None else channel.members()
            system.external.update(Port(port.node, port.channel, k) for k in members)

    def check_allow_pub(self, system: System) -> None:
        """[system.debug] allow_pub = ["node.input", "node.input[k]"]: the inputs `iotad pub` may
        write into when access control is on (docs/access-control.md)."""
        raw = self.data.get("system", {}).get("debug") if isinstance(self.data.get("system"), dict) else None
        if raw is None:
            return
        where = "[system.debug]"
        if not isinstance(raw, dict):
            self.error(where, "must be a table: { allow_pub = [\"node.input[k]\", ...] }")
            return
        for key in sorted(set(raw) - {"allow_pub"}):
            self.error(where, f"unknown key {key!r} (expected allow_pub)")
        entries = raw.get("allow_pub", [])
        if not isinstance(entries, list):
            self.error(f"{where} allow_pub", "must be a list such as [\"scheduler.req[1]\"]")
            return
        for number, text in enumerate(entries):
            entry = f"{where} allow_pub[{number}]" + (f" ({text!r})".replace("'", '"') if isinstance(text, str) else "")
            resolved = self.resolve(system, text, entry, "input")
            if resolved is not None:
                port, channel = resolved
                members = [port.index] if port.index is not None else channel.members()
                system.allow_pub.update(Port(port.node, port.channel, k) for k in members)

    # ------------------------------------------------------------ [[can]]
    def parse_sweep(self, system: System) -> None:
        """`[sweep]`: what `iotad sweep` reads from a run of this system (docs/sweeps.md)."""
        raw = self.data.get("sweep", {})
        if not isinstance(raw, dict):
            self.error("[sweep]", "must be a table: [sweep] metrics = \"file.py:function\"")
            return
        for key in sorted(set(raw) - _SWEEP_KEYS):
            self.error("[sweep]", f"unknown key {key!r} (expected one of {sorted(_SWEEP_KEYS)})")
        if "metrics" not in raw:
            return
        ref = raw["metrics"]
        if not isinstance(ref, str) or ":" not in ref or not all(ref.rsplit(":", 1)):
            self.error("[sweep]", f"metrics must be \"file.py:function\" or \"module:function\", got {ref!r}")
            return
        where, function = ref.rsplit(":", 1)
        if where.endswith(".py"):  # as python = "file.py:Class": relative to this file; only `iotad sweep`
            ref = f"{(self.base / where).resolve()}:{function}"  # needs it there, and says so
        system.sweep_metrics = ref

    def check_after(self, system: System) -> None:
        for node in system.nodes.values():
            for other in node.after:
                if other == node.name:
                    self.error(node.entry, "a node cannot start after itself")
                elif other not in system.nodes:
                    bus = system.buses.get(other)
                    hint = f" (bus {other!r} has no logger node: it says log = false)" if bus is not None else ""
                    self.error(node.entry, f"after names unknown node {other!r}{hint}")
        cycle = _after_cycle({name: [o for o in node.after if o in system.nodes and o != name]
                              for name, node in system.nodes.items()})
        if cycle:
            self.error(system.nodes[cycle[0]].entry,
                       f"after goes round in a circle, so none of these could ever start: {' -> '.join(cycle)} "
                       f"(each waits for the next to be live)")

    def parse_buses(self, system: System) -> None:
        for number, raw in enumerate(self.table_list("can"), 1):
            entry = f"[[can]] #{number}" + (f" (name={raw['name']!r})".replace("'", '"') if "name" in raw else "")
            for key in sorted(set(raw) - _CAN_KEYS):
                self.error(entry, f"unknown key {key!r} (expected one of {sorted(_CAN_KEYS)})")
            name = raw.get("name")
            if not isinstance(name, str) or not _SYSTEM_NAME.match(name):
                self.error(entry, f"name must be one key chunk (letters, digits, _ and -), got {name!r}")
                continue
            if name in system.buses or name in system.nodes:
                self.error(entry, f"the name {name!r} is already taken by another bus or a node")
                continue
            interface = raw.get("interface")
            if not isinstance(interface, str) or not interface:
                self.error(entry, "interface must name a python-can interface, e.g. \"socketcan\" or "
                                  "\"udp_multicast\"")
                continue
            bus = CanBusSpec(name, interface, entry=entry)
            if "channel" in raw:
                if isinstance(raw["channel"], str) and raw["channel"]:
                    bus.channel = raw["channel"]
                else:
                    self.error(entry, f"channel must be a string such as \"vcan0\", got {raw['channel']!r}")
                if interface == "env":
                    self.error(entry, "interface = \"env\" takes the channel from IOTAD_CAN_CHANNEL too: "
                                      "leave channel out")
            bitrate = raw.get("bitrate", bus.bitrate)
            if isinstance(bitrate, bool) or not isinstance(bitrate, int) or not 10_000 <= bitrate <= 1_000_000:
                self.error(entry, f"bitrate must be an integer from 10000 to 1000000 bit/s, got {bitrate!r}")
            else:
                bus.bitrate = bitrate
            if "log" in raw:
                if isinstance(raw["log"], bool):
                    bus.log = raw["log"]
                else:
                    self.error(entry, f"log must be true or false, got {raw['log']!r}")
            options = raw.get("options", {})
            if not isinstance(options, dict):
                self.error(entry, "options must be a table of python-can bus arguments")
            else:
                bus.options = dict(options)
            stations = raw.get("stations")
            if not isinstance(stations, list) or not stations or not all(isinstance(n, str) for n in stations):
                self.error(entry, "stations must be a non-empty list of node names")
                continue
            for station in stations:
                if station not in system.nodes:
                    self.error(entry, f"station {station!r} is not a node (nodes: {', '.join(system.nodes)})")
                elif system.bus_of(station) is not None:
                    self.error(entry, f"node {station!r} is already a station of bus {system.bus_of(station).name!r}")
                elif stations.count(station) > 1:
                    self.error(entry, f"station {station!r} is listed twice")
                    break
                else:
                    bus.stations.append(station)
            system.buses[name] = bus

    def check_stations(self, system: System) -> None:
        for bus in system.buses.values():
            for station in bus.stations:
                if station in self.unbuilt:
                    continue
                channels = system.nodes[station].channels
                for name, direction in ((CAN_TX, "output"), (CAN_RX, "input")):
                    channel = channels.get(name)
                    if channel is None or channel.direction != direction or channel.size is not None:
                        self.error(bus.entry, f"station {station!r} needs a plain {direction} channel {name!r} "
                                              f"of type canFrame to sit on a CAN bus")
                    elif channel.type is None or getattr(channel.type, "name", None) != "canFrame":
                        self.error(bus.entry, f"{station}.{name} carries {_type_name(channel.type)}, not canFrame")
            self.check_node_ids(bus)

    # Two devices answering one node id garble each other's replies; two hosts commanding one
    # axis bypass the scheduler that should arbitrate them. Neither shows as an error on a real
    # bus (the frames are well-formed), only as a robot that misbehaves: said here, before it runs.
    def check_node_ids(self, bus) -> None:
        claimed: dict[tuple[str, int], tuple[str, str]] = {}
        for station in bus.stations:
            role, ids = self.can_claims.get(station, (None, {}))
            for node_id, label in sorted(ids.items()):
                first = claimed.setdefault((role, node_id), (station, label))
                if first[0] != station:
                    what = "answered by two devices" if role == "device" else "commanded by two hosts"
                    self.error(bus.entry, f"CAN node id {node_id} is {what}: {first[0]} ({first[1]}) and "
                                          f"{station} ({label}); every axis on a bus needs a node id of its own")

    def check_inputs_covered(self, system: System) -> None:
        bound = {b.target for b in system.bindings}
        bound |= {Port(station, CAN_RX, None) for bus in system.buses.values() for station in bus.stations}
        bound |= {Port(bus, CAN_RX, None) for bus in system.buses}  # a bus logger's, fed by its bus
        for node in system.nodes.values():
            restart = node.channels.get(PEER_RESTART)
            if restart is not None and restart.direction == "input":
                # fed by the node host (restart notices of its peers), never by a binding
                if restart.size is not None or (restart.type is not None and not hasattr(restart.type, "members")):
                    self.error(node.entry, f"input {PEER_RESTART} (restart notices from the node host) must be "
                                           f"one plain input with no value or an enum of channel names")
                bound.add(Port(node.name, PEER_RESTART, None))
            missing = [str(Port(node.name, channel.name, k)) for channel in node.channels.values()
                       if channel.direction == "input" for k in channel.members()
                       if Port(node.name, channel.name, k) not in bound | system.external]
            if missing:
                shown = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
                self.error(node.entry, f"input(s) {shown} neither bound nor declared external "
                                       f"(add a [[bind]] or external = [\"{missing[0]}\"])")


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


# ---------------------------------------------------------------------------- helpers

SLOW_BUILD = 10.0  # seconds a node's IOTA may take to build before the user is told


@contextmanager
def _said_if_slow(message: str):
    """Say `message` on stderr if the block is still running after SLOW_BUILD seconds: building
    a node runs its code (module, init), which may block, and nothing else would be printed."""
    timer = threading.Timer(SLOW_BUILD, lambda: print(f"iotad: {message}", file=sys.stderr, flush=True))
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        timer.cancel()


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0 and not math.isinf(value)


def _queue_size(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 1


def _endpoint_list_problem(value: Any) -> str:
    """Why `value` is not a list of zenoh endpoints ("" when it is one)."""
    if not isinstance(value, list):
        return f"expected a list of endpoints such as [\"tcp/127.0.0.1:7447\"], got {value!r}"
    return next((problem for problem in map(endpoint_problem, value) if problem), "")


def _same_type(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.json_schema() == b.json_schema()


def _type_name(t: Any) -> str:
    return "no value" if t is None else str(t)


def with_port(endpoints: list[str], port: int) -> list[str]:
    """The endpoints with their port replaced (`iotad run --port`)."""
    out = []
    for endpoint in endpoints:
        head, sep, tail = endpoint.rpartition(":")
        out.append(f"{head}:{port}" if sep and tail.split("#")[0].isdigit() else endpoint)
    return out


def _after_cycle(after: dict[str, list[str]]) -> list[str]:
    """A cycle of `after` (node -> the nodes it starts after) as [a, b, ..., a], each starting
    after the next, or []."""
    try:
        TopologicalSorter(after).prepare()
    except CycleError as exc:
        return list(reversed(exc.args[1]))  # graphlib lists it in the other direction
    return []

    for node in after:
        if node not in state:
            found = walk(node)
            if found:
                return found
    return []
