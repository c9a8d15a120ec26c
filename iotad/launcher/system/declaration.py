"""The declaration of a system: what a system file says, parsed, with no IOTA instantiated.

    declaration = read_declaration("figure2.toml")      # or parse_declaration(text) of a copy
    declaration.nodes["scheduler"].params, declaration.bindings   # (Port, Port) pairs, as written

Parsing reads the TOML (this is the one module of iotad that does), checks the shape of every
entry (keys, names, numbers, endpoints, hosts, buses, `after`) and adds the implicit nodes: one
bus logger per `[[can]]` bus that logs (`launcher/system/bus_logger.py` says why). Problems are
collected in `errors`, one line per problem naming the file and the entry; what parsed is kept,
so that a reader of a recorded copy (recorder, delivery check, plots, `iotad check`) gets what
it can. Checking the declaration against the nodes' IOTAs (channel tables, types, switching
times, families) is `launcher/system/system_file.py`'s `load_system`, a separate step.

The file format is documented in `launcher/system/system_file.py` and docs/system-file.md.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from graphlib import CycleError, TopologicalSorter
from pathlib import Path
from types import MappingProxyType
from typing import Any, Callable, Mapping

from iotad.can.canopen_ids import canopen_nodes
from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT, endpoint_problem, reachable
from iotad.kernel.ports import Port
from iotad.kernel.text_file import read_text_file
from iotad.kernel.types import HUGE_INT
from iotad.launcher.goals import BUILTIN, Goal, parse_goals

RESTART_MODES = ("never", "on-failure", "always")
LOOPBACK_LISTEN = ["tcp/127.0.0.1:0"]
DEFAULT_INPUT_QUEUE = 1000     # inputs a node host holds for its engine before it drops (and counts) more
LOGGER_REF = "iotad.can.frame_log:BusLogger"  # the class of a bus's logger node (bus_logger.py)
CANOPEN_LOGGER_REF = "iotad.can.canopen_frame_log:CanopenBusLogger"  # ... of a bus with CiA 402 stations
LOGGER_LAG = 0.1  # seconds a frame may wait in the logger before its log entry is late (a deadline miss)
LOGGER_BATCH = 0.005  # seconds from the first frame of a burst the logger writes to the burst
_PATH = re.compile(r"^[A-Za-z_][\w-]*(/[A-Za-z_][\w-]*)*$")
_SYSTEM_NAME = re.compile(r"^[A-Za-z_][\w-]*$")

_SYSTEM_KEYS = {"name", "time_unit", "endpoints", "hub_host", "heartbeat_period", "heartbeat_timeout",
                "start_timeout", "clock_bound", "clock_period", "link_timeout", "external", "deadline_tolerance", "arrival_tolerance", "input_queue", "debug",
                "start_gate", "strict"}
# In TOML a key written after a [[node]] or [[bind]] table belongs to that table.
TABLE_HINT = {"external": " (a top-level key must come before the first table; or put it in [system])"}
_NODE_KEYS = {"name", "spec", "iota", "python", "params", "restart", "max_restarts", "backoff", "host",
              "after", "policy", "seed", "required", "input_queue"}
_TOP_KEYS = {"system", "node", "bind", "external", "hosts", "can", "ros2", "sweep", "goals"}
_SWEEP_KEYS = {"metrics"}
_CAN_KEYS = {"name", "interface", "channel", "bitrate", "stations", "options", "log"}


class SystemFileError(Exception):
    """A system file that cannot run. `errors` holds one line per problem, each naming the entry."""

    def __init__(self, errors: list[str]):
        super().__init__("\n".join(errors))
        self.errors = errors


@dataclass(frozen=True)
class NodeDecl:
    """One `[[node]]` (or an implicit bus logger) as declared."""

    name: str
    entry: str                       # how messages name it: '[[node]] #1 (name="scheduler")'
    source: dict[str, Any]           # the node host's "source": esprit file or python ref (absolute
    #                                  where the file has a folder; as written in a recorded copy)
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
    bus_logger: bool = False         # an implicit node: the logger of the bus it is named after
    file: str | None = None          # its spec or python file as the system file writes it (code_by_hash.py)


@dataclass(frozen=True)
class Bind:
    """One `[[bind]]` as written; `ports` is its (source, target) where both ends parse."""

    entry: str
    source: Any                      # "node.output" or "node.output[k]" (or what the file holds)
    target: Any
    unknown: tuple[str, ...] = ()    # keys other than from and to

    @property
    def ports(self) -> tuple[Port, Port] | None:
        source, target = Port.parsed(self.source), Port.parsed(self.target)
        return None if source is None or target is None else (source, target)


@dataclass(frozen=True)
class CanBusSpec:
    """One `[[can]]` bus: how a real-time node reaches it (python-can) and which nodes sit on it."""

    name: str
    interface: str
    channel: str | None = None
    bitrate: int = 1_000_000
    stations: list[str] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)
    entry: str = ""
    log: bool = True  # real time: a bus logger node named after the bus (iotad/launcher/system/bus_logger.py)

    def port_config(self) -> dict[str, Any]:
        """The node host's `can` config (docs/internals.md): what it opens with python-can."""
        from iotad.launcher.system.can_env import resolved
        interface, channel = resolved(self.interface, self.channel)  # interface = "env": the environment's
        return {"bus": self.name, "interface": interface, "channel": channel,
                "bitrate": self.bitrate, "options": dict(self.options)}


@dataclass(frozen=True)
class Ros2Decl:
    """One `[[ros2]]` table: a channel mapped to a ROS 2 topic, checked with the channels
    (`launcher/system/ros2_tables.py`, docs/ros2.md); `table` is all of it as written."""

    entry: str                       # how messages name it: '[[ros2]] #1 (topic="/cmd")'
    channel: Any                     # "node.channel[k]" (or what the file holds)
    direction: Any                   # "in" | "out" (or what the file holds)
    table: Mapping[str, Any]


@dataclass(frozen=True)
class DebugDecl:
    """`[system.debug]` as written, its shape read; what it names is checked with the channels."""

    table: bool                      # false: something else than a table stands there
    allow_pub: Any = ()              # "node.input[k]" strings (or what the file holds)
    unknown: tuple[str, ...] = ()    # keys other than allow_pub


# where a host's nodes' traces go: "hub" (to the hub's recorder and summary, and to the host's own
# recorder), or "home" (to the host's own recorder only: for a host on a link too thin for them)
TRACES_TO = ("hub", "home")


@dataclass(frozen=True)
class HostSpec:
    name: str
    listen: list[str] = field(default_factory=lambda: list(LOOPBACK_LISTEN))
    traces: str = "hub"


@dataclass(frozen=True)
class Declaration:
    """A system file, parsed: its settings, nodes, bindings, externals, buses and hosts."""

    name: str
    path: Path
    text: str = ""                   # the file's text, as a recording keeps it
    errors: tuple[str, ...] = ()     # what is wrong with it (empty: it parsed whole)
    time_unit: float = 1.0
    listen: list[str] = field(default_factory=lambda: [DEFAULT_HUB_ENDPOINT])
    connect: list[str] = field(default_factory=list)
    hub_host: str | None = None
    heartbeat_period: float = 0.2
    heartbeat_timeout: float = 3.0
    start_timeout: float = 15.0
    # seconds: a host whose clock offset to the hub is known no better than this is a violation
    clock_bound: float = 1e-3
    # seconds between two measurements of a host's clock against the hub's during a run
    clock_period: float = 10.0
    # seconds without setpoints from another host before a node that watches its link (a CAN motor
    # node's `link_timeout`) stops its motors; 0: no such watch (iotad/launcher/system/link_watch.py)
    link_timeout: float = 0.06
    deadline_tolerance: float = 0.002  # seconds a firing may be late before it is a deadline miss
    arrival_tolerance: float = 0.002   # seconds an input may be early (jitter) against its switching time
    input_queue: int = DEFAULT_INPUT_QUEUE  # per node host, unless its [[node]] says otherwise
    # real time: the engines start together once every node is live (false: each as soon as its
    # own node is live, as `after` orders them; docs/internals.md "Start gate")
    start_gate: bool = True
    # any violation, a node's exception or a node never live ends the run non-zero (iotad run --strict)
    strict: bool = False
    nodes: Mapping[str, NodeDecl] = field(default_factory=lambda: MappingProxyType({}))
    binds: tuple[Bind, ...] = ()
    # (where, value as written): external = [...] at the top and in [system]
    externals: tuple[tuple[str, Any], ...] = ()
    debug: DebugDecl | None = None   # [system.debug] (allow_pub), None where the file has none
    hosts: Mapping[str, HostSpec] = field(default_factory=lambda: MappingProxyType({}))
    buses: Mapping[str, CanBusSpec] = field(default_factory=lambda: MappingProxyType({}))
    ros2: tuple[Ros2Decl, ...] = ()  # [[ros2]] tables; checked with the channels (docs/ros2.md)
    # [sweep] metrics: "file.py:function" (absolute where the file has a folder) or "module:function",
    # what `iotad sweep` measures each run with (docs/sweeps.md); nothing else reads it
    sweep_metrics: str | None = None
    # [goals]: what a run must achieve, over the metrics (iotad/launcher/goals.py, docs/stress.md)
    goals: tuple[Goal, ...] = ()
    goals_until: float | None = None  # [goals] until: the virtual seconds they are stated for

    @property
    def file(self) -> str:
        return self.path.name

    @property
    def bindings(self) -> list[tuple[Port, Port]]:
        """(source, target) of every `[[bind]]` whose ends parse, as written (a family unexpanded)."""
        return [ports for ports in (bind.ports for bind in self.binds) if ports is not None]

    @property
    def external(self) -> list[Port]:
        """The inputs declared external (top level and [system]), as written."""
        return [port for _, raw in self.externals if isinstance(raw, list)
                for port in map(Port.parsed, raw) if port is not None]

    @property
    def file_nodes(self) -> list[str]:
        """The names of the nodes the file lists (not the implicit bus loggers)."""
        return [name for name, node in self.nodes.items() if not node.bus_logger]

    def bus_of(self, node: str) -> CanBusSpec | None:
        """The CAN bus `node` is a station of, if any."""
        return next((bus for bus in self.buses.values() if node in bus.stations), None)

    def hub(self) -> list[str]:
        """Where `iotad run` opens this system's hub, as a client reaches it (all interfaces: on loopback)."""
        return [reachable(endpoint) for endpoint in self.listen]


def read_toml(path: str | Path) -> dict[str, Any]:
    """The TOML data of the file at `path` as it is written, checked for nothing: for a sweep file
    (`iotad sweep`), which may be a system file too. This module is the one place iotad parses
    TOML. Raises OSError, or ValueError where the file is no UTF-8 TOML."""
    return tomllib.loads(read_text_file(path))


def read_declaration(path: str | Path, files: Mapping[str, str] | None = None) -> Declaration:
    """The declaration of the system file at `path`; raises `SystemFileError` where it cannot be
    read or is no TOML (a declaration that parsed with errors lists them in `errors`). `files`:
    where this machine has a file the system file names (name as written -> path; an agent's
    run of the hub's file, iotad/launcher/hosts/code_by_hash.py)."""
    path = Path(path)
    try:
        text = read_text_file(path)
    except OSError as exc:
        raise SystemFileError([f"{path}: cannot read: {exc.strerror or exc}"]) from None
    except UnicodeDecodeError:
        raise SystemFileError([f"{path.name}: not UTF-8 text"]) from None
    bom = " (the file starts with a byte-order mark, which TOML does not allow: save it as UTF-8 without BOM)"
    return parse_declaration(text, path, base=path.resolve().parent, bom_hint=bom if text.startswith("\ufeff") else "",
                             files=files)


def parse_declaration(text: str, path: str | Path = "system.toml", *, base: Path | None = None,
                      bom_hint: str = "", files: Mapping[str, str] | None = None) -> Declaration:
    """The declaration `text` holds. `base`: the folder its spec and python files are named from
    (None, for a recorded copy: they are kept as written, not looked up). Raises
    `SystemFileError` where `text` is no TOML."""
    path = Path(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SystemFileError([f"{path.name}: not valid TOML: {exc}{bom_hint}"]) from None
    except RecursionError:
        raise SystemFileError([f"{path.name}: a value is nested too deeply to read"]) from None
    except ValueError:  # tomllib reads no int of more than 4300 digits
        raise SystemFileError([f"{path.name}: an integer of thousands of digits, {HUGE_INT}"]) from None
    return _Parser(path, data, text, base, files).parse()


class _Parser:
    def __init__(self, path: Path, data: dict, text: str, base: Path | None, files: Mapping[str, str] | None = None):
        self.path = path.resolve() if base is not None else path
        self.files = dict(files or {})
        self.data, self.text, self.base, self.errors = data, text, base, []
        self.file = path.name
        self.settings: dict[str, Any] = {"name": self.path.stem.replace(".", "_")}
        self.nodes: dict[str, NodeDecl] = {}
        self.hosts: dict[str, HostSpec] = {}
        self.buses: dict[str, CanBusSpec] = {}

    def error(self, entry: str, message: str) -> None:
        self.errors.append(f"{self.file}: {entry}: {message}")

    def parse(self) -> Declaration:
        for key in sorted(set(self.data) - _TOP_KEYS):
            self.error(key, f"unknown top-level key (expected one of {sorted(_TOP_KEYS)})")
        self.parse_system()
        self.parse_hosts()
        self.parse_nodes()
        self.parse_buses()
        self.parse_sweep()
        self.parse_goals()
        self.add_bus_loggers()  # one implicit node per logged bus, named after it
        self.check_after()  # after the loggers: a node may start after a bus's logger
        raw_system = self.data.get("system")
        in_system = raw_system.get("external", []) if isinstance(raw_system, dict) else []
        externals = (("external", self.data.get("external", [])),) + \
            ((("[system] external", in_system),) if in_system else ())
        binds = tuple(self.parse_binds())
        return Declaration(path=self.path, text=self.text, errors=tuple(self.errors), nodes=MappingProxyType(self.nodes),
                           binds=binds, externals=externals,
                           debug=self.parse_debug(raw_system.get("debug") if isinstance(raw_system, dict) else None),
                           hosts=MappingProxyType(self.hosts), buses=MappingProxyType(self.buses),
                           ros2=tuple(self.parse_ros2()), **self.settings)

    def parse_debug(self, raw: Any) -> DebugDecl | None:
        """`[system.debug]`: its shape (the names it lists are checked with the channels)."""
        if raw is None:
            return None
        if not isinstance(raw, dict):
            return DebugDecl(table=False)
        return DebugDecl(table=True, allow_pub=raw.get("allow_pub", []), unknown=tuple(sorted(set(raw) - {"allow_pub"})))

    def parse_ros2(self) -> list[Ros2Decl]:
        """`[[ros2]]` tables, each named as messages name it (what they map is checked with the channels)."""
        tables = []
        for number, raw in enumerate(self.table_list("ros2"), 1):
            entry = f"[[ros2]] #{number}" + (f" (topic=\"{raw['topic']}\")" if isinstance(raw.get("topic"), str) else "")
            tables.append(Ros2Decl(entry, raw.get("channel"), raw.get("direction"), MappingProxyType(dict(raw))))
        return tables

    # ------------------------------------------------------------ [system] and [hosts]
    def parse_system(self) -> None:
        raw = self.data.get("system", {})
        entry = "[system]"
        system = self.settings
        if not isinstance(raw, dict):
            self.error(entry, "must be a table")
            return
        for key in sorted(set(raw) - _SYSTEM_KEYS):
            self.error(entry, f"unknown key {key!r} (expected one of {sorted(_SYSTEM_KEYS)})")
        if "name" in raw:
            self.take(raw, "name", system, entry, _chunk, "one key chunk (letters, digits, _ and -)")
        elif not _SYSTEM_NAME.match(system["name"]):
            self.error(entry, f"no name given and the file name {system['name']!r} is not a valid one")
        for key in ("time_unit", "heartbeat_period", "heartbeat_timeout", "start_timeout", "clock_bound", "clock_period",
                    "deadline_tolerance", "arrival_tolerance"):
            if key in raw:
                value = raw[key]
                if key == "time_unit" and _positive(value) and value < 1e-6:
                    # recordings keep times in whole nanoseconds: finer spec units would merge events
                    self.error(entry, f"time_unit must be at least 1e-6 s (a microsecond), got {value!r}")
                elif _positive(value):
                    system[key] = float(value)
                else:
                    self.error(entry, f"{key} must be a positive number of seconds, got {value!r}")
        self.take(raw, "link_timeout", system, entry, lambda v: not isinstance(v, bool) and (v == 0 or _positive(v)), "seconds >= 0 (0: off)")
        self.take(raw, "start_gate", system, entry, _flag, "true or false")
        self.take(raw, "strict", system, entry, _flag, "true or false")
        self.take(raw, "input_queue", system, entry, _queue_size, "a whole number of inputs >= 1")
        period = system.get("heartbeat_period", Declaration.heartbeat_period)
        timeout = system.get("heartbeat_timeout", Declaration.heartbeat_timeout)
        if period >= timeout:
            self.error(entry, f"heartbeat_period ({period:g} s) must be below heartbeat_timeout "
                              f"({timeout:g} s), or every node is killed as frozen between "
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
                        system[key] = value
            if not system.get("listen", True):
                self.error(entry, "endpoints.listen is empty: the hub must listen somewhere")
        self.take(raw, "hub_host", system, entry, lambda v: isinstance(v, str), "a host name")

    def parse_hosts(self) -> None:
        raw = self.data.get("hosts", {})
        if not isinstance(raw, dict):
            self.error("[hosts]", "must be a table of [hosts.NAME] tables")
            return
        for name, table in raw.items():
            entry = f"[hosts.{name}]"
            if not isinstance(table, dict):
                self.error(entry, "must be a table")
                continue
            for key in sorted(set(table) - {"listen", "traces"}):
                self.error(entry, f"unknown key {key!r} (expected listen or traces)")
            listen = list(LOOPBACK_LISTEN)
            if "listen" in table:
                value = [table["listen"]] if isinstance(table["listen"], str) else table["listen"]
                problem = _endpoint_list_problem(value) or ("" if value else "an empty list: it must listen somewhere")
                if problem:
                    self.error(entry, f"listen: {problem}")
                else:
                    listen = value
            traces = table.get("traces", "hub")
            if traces not in TRACES_TO:
                self.error(entry, f"traces must be \"hub\" (the hub hears this host's nodes' traces and records "
                                  f"them) or \"home\" (only this host's own recording holds them), got {traces!r}")
                traces = "hub"
            self.hosts[name] = HostSpec(name, listen, traces)

    # ------------------------------------------------------------ [[node]]
    def table_list(self, key: str) -> list:
        raw = self.data.get(key, [])
        if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
            self.error(f"[[{key}]]", f"must be an array of tables ([[{key}]] entries)")
            return []
        return raw

    def parse_nodes(self) -> None:
        raw_nodes = self.table_list("node")
        if not raw_nodes and "node" not in self.data:
            self.error("[[node]]", "the system has no nodes")
        for number, raw in enumerate(raw_nodes, 1):
            entry = f"[[node]] #{number}" + (f" (name={raw['name']!r})".replace("'", '"') if "name" in raw else "")
            node = self.parse_node(raw, entry)
            if node is None:
                continue
            if node.name in self.nodes:
                self.error(entry, f"a node named {node.name!r} is already {self.nodes[node.name].entry}")
                continue
            self.nodes[node.name] = node
        hosts_used = {n.host for n in self.nodes.values() if n.host is not None}
        if hosts_used and any(n.host is None for n in self.nodes.values()):
            self.error("[[node]]", "either every node names its host or none does")
        hub_host = self.settings.get("hub_host")
        if hub_host is None and hosts_used:
            hub_host = self.settings["hub_host"] = next(n.host for n in self.nodes.values())
        if hub_host is not None and hosts_used and hub_host not in hosts_used | set(self.hosts):
            self.error("[system]", f"hub_host {hub_host!r} is not a host of any node")
        if hub_host is not None and hub_host in self.hosts and self.hosts[hub_host].traces == "home":
            self.error(f"[hosts.{hub_host}]", "traces = \"home\" on the hub's own host: its nodes' traces are "
                                              "at the hub already (give it to a host on a thin link to the hub)")

    def parse_node(self, raw: dict, entry: str) -> NodeDecl | None:
        for key in sorted(set(raw) - _NODE_KEYS):
            self.error(entry, f"unknown key {key!r} (expected one of {sorted(_NODE_KEYS)})"
                              + TABLE_HINT.get(key, ""))
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
            file = self.file_named(raw["spec"], entry, "spec file", ".iota")
            if file is None:
                return None
            if "iota" in raw and not isinstance(raw["iota"], str):
                self.error(entry, f"iota must be an IOTA name, got {raw['iota']!r}")
                return None
            source = {"kind": "esprit", "file": file, "iota": raw.get("iota")}
            written = raw["spec"]
        else:
            written = None  # "module:Class" names no file
            if "iota" in raw:
                self.error(entry, "iota only goes with spec = \"file.iota\"; python names its class after ':'")
            ref = raw["python"]
            if not isinstance(ref, str) or ":" not in ref:
                self.error(entry, f"python must be \"file.py:Class\" or \"module:Class\", got {ref!r}")
                return None
            where, cls = ref.rsplit(":", 1)
            if where.endswith(".py"):
                file = self.file_named(where, entry, "python file", ".py")
                if file is None:
                    return None
                ref = f"{file}:{cls}"
                written = where
            source = {"kind": "python", "ref": ref}
        node: dict[str, Any] = {"name": name, "entry": entry, "source": source, "file": written}
        params = raw.get("params", {})
        if not isinstance(params, dict):
            self.error(entry, "params must be a table, e.g. params = { N = 2 }")
        else:
            if self.base is not None:  # a robot's URDF named relative to this file (a world's `urdf`)
                from iotad.kernel.package_files import absolute_files
                params = absolute_files(params, self.base)
            node["params"] = params
        restart = raw.get("restart", NodeDecl.restart)
        if restart not in RESTART_MODES:
            self.error(entry, f"restart must be one of {', '.join(RESTART_MODES)}, got {restart!r}")
        node["restart"] = restart
        self.take(raw, "max_restarts", node, entry, lambda v: _whole(v) and v >= 0, "a whole number >= 0")
        if "backoff" in raw:
            if _positive(raw["backoff"]) or raw["backoff"] == 0:
                node["backoff"] = float(raw["backoff"])
            else:
                self.error(entry, f"backoff must be a number of seconds >= 0, got {raw['backoff']!r}")
        self.take(raw, "host", node, entry, _chunk, "a host name")
        after = raw.get("after", [])
        if isinstance(after, str):
            after = [after]
        if not isinstance(after, list) or not all(isinstance(a, str) for a in after):
            self.error(entry, f"after must be a list of node names, got {raw.get('after')!r}")
        else:
            node["after"] = after
        self.take(raw, "policy", node, entry, lambda v: v in ("eager", "latest", "random"),
                  "\"eager\", \"latest\" or \"random\"")
        self.take(raw, "seed", node, entry, lambda v: _whole(v) and 0 <= v < 2**64, "a whole number from 0 to 2**64 - 1")
        self.take(raw, "required", node, entry, _flag, "true or false")
        self.take(raw, "input_queue", node, entry, _queue_size, "a whole number of inputs >= 1")
        return NodeDecl(**node)

    def take(self, raw: dict, key: str, into: dict, entry: str, fits: Callable[[Any], bool], wanted: str) -> None:
        """`raw[key]` into `into` where it `fits`; else the error that says it must be `wanted`."""
        if key not in raw:
            return
        if fits(raw[key]):
            into[key] = raw[key]
        else:
            self.error(entry, f"{key} must be {wanted}, got {raw[key]!r}")

    def file_named(self, written: str, entry: str, what: str, suffix: str) -> str | None:
        """The absolute file a node names, relative to the system file's folder; as written in a
        recorded copy, which has no folder (its files are not looked up)."""
        if self.base is None:
            return written
        from iotad.kernel.package_files import is_package_ref, package_file

        if is_package_ref(written):  # "nodes.scheduler:program_scheduler.iota": from any folder
            try:
                return str(package_file(written))
            except ValueError as exc:
                self.error(entry, f"{what} {written!r}: {exc}")
                return None
        file = Path(self.files[written]) if written in self.files else (self.base / written).resolve()
        if not file.is_file():
            found = f"is a folder; name the {suffix} file in it" if file.is_dir() else "not found"
            self.error(entry, f"{what} {written!r} {found} (looked at {file})")
            return None
        return str(file)

    def parse_binds(self) -> list[Bind]:
        binds = []
        for number, raw in enumerate(self.table_list("bind"), 1):
            entry = f"[[bind]] #{number}" + (f" (from={raw['from']!r})".replace("'", '"') if "from" in raw else "")
            binds.append(Bind(entry, raw.get("from"), raw.get("to"), tuple(sorted(set(raw) - {"from", "to"}))))
        return binds

    def check_after(self) -> None:
        for node in self.nodes.values():
            for other in node.after:
                if other == node.name:
                    self.error(node.entry, "a node cannot start after itself")
                elif other not in self.nodes:
                    bus = self.buses.get(other)
                    hint = f" (bus {other!r} has no logger node: it says log = false)" if bus is not None else ""
                    self.error(node.entry, f"after names unknown node {other!r}{hint}")
        cycle = _after_cycle({name: [o for o in node.after if o in self.nodes and o != name]
                              for name, node in self.nodes.items()})
        if cycle:
            self.error(self.nodes[cycle[0]].entry,
                       f"after goes round in a circle, so none of these could ever start: {' -> '.join(cycle)} "
                       f"(each waits for the next to be live)")

    def parse_sweep(self) -> None:
        """`[sweep]`: what `iotad sweep` measures in each run of this system (docs/sweeps.md)."""
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
        if where.endswith(".py") and self.base is not None:  # as python = "file.py:Class": relative to
            ref = f"{(self.base / where).resolve()}:{function}"  # this file; `iotad sweep` looks for it
        self.settings["sweep_metrics"] = ref

    def parse_goals(self) -> None:
        """`[goals]`: conditions over the run's metrics (goals.py parses them; nothing is evaluated)."""
        if "goals" not in self.data:
            return
        goals, until, errors = parse_goals(self.data["goals"])
        for line in errors:
            self.errors.append(f"{self.file}: {line}")
        measured = [goal for goal in goals if goal.metric not in BUILTIN]
        if measured and "sweep_metrics" not in self.settings:
            self.error("[goals]", f"{measured[0].metric} is measured by no [sweep] metrics hook (only "
                       f"{', '.join(BUILTIN)} is counted without one)")
        self.settings["goals"] = tuple(goals)
        self.settings["goals_until"] = until

    def parse_buses(self) -> None:
        for number, raw in enumerate(self.table_list("can"), 1):
            entry = f"[[can]] #{number}" + (f" (name={raw['name']!r})".replace("'", '"') if "name" in raw else "")
            for key in sorted(set(raw) - _CAN_KEYS):
                self.error(entry, f"unknown key {key!r} (expected one of {sorted(_CAN_KEYS)})")
            name = raw.get("name")
            if not isinstance(name, str) or not _SYSTEM_NAME.match(name):
                self.error(entry, f"name must be one key chunk (letters, digits, _ and -), got {name!r}")
                continue
            if name in self.buses or name in self.nodes:
                self.error(entry, f"the name {name!r} is already taken by another bus or a node")
                continue
            interface = raw.get("interface")
            if not isinstance(interface, str) or not interface:
                self.error(entry, "interface must name a python-can interface, e.g. \"socketcan\" or "
                                  "\"udp_multicast\"")
                continue
            bus: dict[str, Any] = {"name": name, "interface": interface, "entry": entry, "stations": []}
            if "channel" in raw:
                if isinstance(raw["channel"], str) and raw["channel"]:
                    bus["channel"] = raw["channel"]
                else:
                    self.error(entry, f"channel must be a string such as \"vcan0\", got {raw['channel']!r}")
                if interface == "env":
                    self.error(entry, "interface = \"env\" takes the channel from IOTAD_CAN_CHANNEL too: "
                                      "leave channel out")
            bitrate = raw.get("bitrate", CanBusSpec.bitrate)
            if isinstance(bitrate, bool) or not isinstance(bitrate, int) or not 10_000 <= bitrate <= 1_000_000:
                self.error(entry, f"bitrate must be an integer from 10000 to 1000000 bit/s, got {bitrate!r}")
            else:
                bus["bitrate"] = bitrate
            self.take(raw, "log", bus, entry, _flag, "true or false")
            options = raw.get("options", {})
            if not isinstance(options, dict):
                self.error(entry, "options must be a table of python-can bus arguments")
            else:
                bus["options"] = dict(options)
            stations = raw.get("stations")
            if not isinstance(stations, list) or not stations or not all(isinstance(n, str) for n in stations):
                self.error(entry, "stations must be a non-empty list of node names")
                continue
            for station in stations:
                if station not in self.nodes:
                    self.error(entry, f"station {station!r} is not a node (nodes: {', '.join(self.nodes)})")
                elif self.bus_of(station) is not None:
                    self.error(entry, f"node {station!r} is already a station of bus {self.bus_of(station).name!r}")
                elif stations.count(station) > 1:
                    self.error(entry, f"station {station!r} is listed twice")
                    break
                else:
                    bus["stations"].append(station)
            self.buses[name] = CanBusSpec(**bus)

    def bus_of(self, node: str) -> CanBusSpec | None:
        return next((bus for bus in self.buses.values() if node in bus.stations), None)

    def add_bus_loggers(self) -> None:
        """The logger node of every bus that logs (`CanBusSpec.log`), named after it (bus_logger.py)."""
        unit = self.settings.get("time_unit", Declaration.time_unit)
        for bus in self.buses.values():
            if not bus.log or bus.name in self.nodes:
                continue
            hosts = [self.nodes[s].host for s in bus.stations if s in self.nodes]
            # lag and batch: in the system's time unit
            params = {"bitrate": bus.bitrate, "lag": LOGGER_LAG / unit, "batch": LOGGER_BATCH / unit}
            ref = LOGGER_REF
            canopen = canopen_nodes(self.nodes[s].params for s in bus.stations if s in self.nodes)
            if canopen:  # its log names each frame by family, CANopen or CAN Simple
                ref, params["canopen"] = CANOPEN_LOGGER_REF, sorted(canopen)
            self.nodes[bus.name] = NodeDecl(
                name=bus.name, entry=f"{bus.entry}'s bus logger", source={"kind": "python", "ref": ref},
                params=params, host=next((h for h in hosts if h is not None), None), bus_logger=True)


def _positive(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0 and not math.isinf(value)


def _whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _chunk(value: Any) -> bool:
    """One chunk of a key (a system, bus or host name): letters, digits, _ and -."""
    return isinstance(value, str) and _SYSTEM_NAME.match(value) is not None


def _flag(value: Any) -> bool:
    return isinstance(value, bool)


def _queue_size(value: Any) -> bool:
    return _whole(value) and value >= 1


def _endpoint_list_problem(value: Any) -> str:
    """Why `value` is not a list of zenoh endpoints ("" when it is one)."""
    if not isinstance(value, list):
        return f"expected a list of endpoints such as [\"tcp/127.0.0.1:7447\"], got {value!r}"
    return next((problem for problem in map(endpoint_problem, value) if problem), "")


def _after_cycle(after: dict[str, list[str]]) -> list[str]:
    """A cycle of `after` (node -> the nodes it starts after) as [a, b, ..., a], each starting
    after the next, or []."""
    try:
        TopologicalSorter(after).prepare()
    except CycleError as exc:
        return list(reversed(exc.args[1]))  # graphlib lists it in the other direction
    return []
