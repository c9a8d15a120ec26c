"""A node host's configuration (the JSON the launcher writes, docs/internals.md "Node host"):
parsed and checked up front, so that a bad config is one clear line, never a traceback."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from iotad.node_host.transport import DEFAULT_LISTEN


class ConfigError(ValueError):
    """The config is not usable; `str()` is one line for the user."""


# The node host's exit status for an error in its configuration (a bad config, a spec that does
# not load, a CAN bus that cannot open...): starting it again cannot mend it, so the launcher
# ends the node at once instead of restarting it (docs/failures.md).
CONFIGURATION_ERROR = 2


@dataclass
class NodeConfig:
    system: str
    path: str
    source: dict[str, Any]
    params: dict[str, Any] = field(default_factory=dict)
    time_unit: float = 1.0
    origin: float | None = None
    listen: list[str] = field(default_factory=lambda: list(DEFAULT_LISTEN))
    connect: list[str] = field(default_factory=list)
    inputs: dict[str, list[str]] = field(default_factory=dict)  # "chan" or "chan/k" -> bound keys
    # "chan" or "chan/k" of an output -> the node paths bound to read it (restart notices only)
    readers: dict[str, list[str]] = field(default_factory=dict)
    heartbeat_period: float = 0.5
    # Seconds a firing may come after its window's end before it counts as a deadline miss: a
    # Python process wakes some tens of microseconds late, which is not the spec's fault.
    deadline_tolerance: float = 0.002
    # Seconds an input may arrive sooner than its switching time and still be accepted: arrival
    # times carry transport jitter that the sender's paced send times did not have.
    arrival_tolerance: float = 0.002
    # Seconds a node may hold its trace events before publishing them on @trace in one burst:
    # one recorder wake-up per period instead of one per event (and at most this much of the
    # trace lost if the node is killed). 0: publish whenever the engine is about to block.
    trace_period: float = 0.02
    policy: str = "eager"
    seed: int = 0
    zenoh: dict[str, Any] = field(default_factory=dict)  # extra zenoh config: path -> JSON value
    # The CAN bus this node is a station of (its can_tx/can_rx channels): bus, interface, channel,
    # bitrate, options (python-can arguments). None: the node has no CAN port.
    can: dict[str, Any] | None = None
    # How many inputs may wait for the engine (the system file's `input_queue`); past that an
    # input is dropped and counted (an `input_overflow` violation). None: unbounded.
    input_queue: int | None = 1000
    # How many times the launcher has restarted this node before this process (0: its first):
    # its heartbeats say so, so that a tool attached later (`iotad top`) counts them too.
    restarts: int = 0
    # The launcher's start gate (a liveliness key, `iota/<system>/@go/<host>`): the node declares
    # everything, goes live and waits for a token on this key before its engine starts, so that
    # no engine runs while other nodes are still importing and building on the same cores.
    # None: the engine starts at once (a restart, or a node run by hand).
    start_gate: str | None = None
    # Where this host's launcher publishes the hub's origin on this host's clock each time it
    # measures the clock again (`iota/<system>/@origin/<host>`, a host other than the hub's): the
    # node's clock follows it (iotad/node_host/clock_correction.py). None: the origin above holds.
    follow_origin: str | None = None
    # The system file's host of this node (its `host = NAME`), said in its @spec answer so that
    # `iotad ls` and `iotad top` show where each node runs. None: a system on one machine.
    host: str | None = None

    @property
    def name(self) -> str:
        """The IOTA's instance name: the last chunk of its path (`buggy/wander` -> `wander`)."""
        return self.path.rsplit("/", 1)[-1]


_KNOWN = {"system", "path", "source", "params", "time_unit", "origin", "listen", "connect", "inputs", "readers",
          "heartbeat_period", "deadline_tolerance", "arrival_tolerance", "trace_period", "policy", "seed", "zenoh", "can",
          "input_queue", "restarts", "start_gate", "follow_origin", "host"}


def load(path: str | Path) -> NodeConfig:
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read config {path}: {exc.strerror or exc}") from None
    return parse(text, str(path))


def parse(text: str, where: str = "config") -> NodeConfig:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{where}: not JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") from None
    return from_dict(data, where)


def _chunks_ok(text: str) -> bool:
    # zenoh key chunks: no wildcards, no empty chunks, no leading '@' (we use those for @trace etc.)
    return bool(text) and all(c and not c.startswith("@") and not set(c) & set("*$?#") for c in text.split("/"))


def from_dict(data: Any, where: str = "config") -> NodeConfig:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a JSON object")
    unknown = set(data) - _KNOWN
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}")
    for key in ("system", "path", "source"):
        if key not in data:
            raise ConfigError(f"{where}: missing required key {key!r}")
    for key in ("system", "path"):
        if not isinstance(data[key], str) or not _chunks_ok(data[key]) or (key == "system" and "/" in data[key]):
            raise ConfigError(f"{where}: {key} must be a plain key-expression name, got {data[key]!r}")
    source = data["source"]
    if not isinstance(source, dict) or source.get("kind") not in ("esprit", "python"):
        raise ConfigError(f"{where}: source must be {{\"kind\": \"esprit\"|\"python\", ...}}")
    if source["kind"] == "esprit" and not isinstance(source.get("file"), str):
        raise ConfigError(f"{where}: an esprit source needs \"file\"")
    if source["kind"] == "python" and not isinstance(source.get("ref"), str):
        raise ConfigError(f"{where}: a python source needs \"ref\" (\"file.py:Class\" or \"module:Class\")")
    config = NodeConfig(system=data["system"], path=data["path"], source=dict(source))
    params = data.get("params", {})
    if not isinstance(params, dict):
        raise ConfigError(f"{where}: params must be an object")
    config.params = params
    if "restarts" in data:
        value = data["restarts"]
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise ConfigError(f"{where}: restarts must be a whole number >= 0, got {value!r}")
        config.restarts = value
    if data.get("start_gate") is not None:
        gate = data["start_gate"]
        if not isinstance(gate, str) or not gate or set(gate) & set("*$?#"):
            raise ConfigError(f"{where}: start_gate must be a liveliness key without wildcards "
                              f"(the launcher's iota/<system>/@go/<host>), got {gate!r}")
        config.start_gate = gate
    if data.get("follow_origin") is not None:
        key = data["follow_origin"]
        if not isinstance(key, str) or not key or set(key) & set("*$?#"):
            raise ConfigError(f"{where}: follow_origin must be a key without wildcards "
                              f"(the launcher's iota/<system>/@origin/<host>), got {key!r}")
        if data.get("origin") is None:
            raise ConfigError(f"{where}: follow_origin needs an origin to correct")
        config.follow_origin = key
    if data.get("host") is not None:
        if not isinstance(data["host"], str) or not _chunks_ok(data["host"]) or "/" in data["host"]:
            raise ConfigError(f"{where}: host must be a host name of the system file, got {data['host']!r}")
        config.host = data["host"]
    if "trace_period" in data:
        value = data["trace_period"]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not (0 <= value <= 1):
            raise ConfigError(f"{where}: trace_period must be a number of seconds in [0, 1], got {value!r}")
        config.trace_period = float(value)
    for key in ("time_unit", "heartbeat_period", "deadline_tolerance", "arrival_tolerance"):
        if key in data:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (value > 0) or math.isinf(value):
                raise ConfigError(f"{where}: {key} must be a positive number, got {value!r}")
            setattr(config, key, float(value))
    if data.get("origin") is not None:
        if isinstance(data["origin"], bool) or not isinstance(data["origin"], (int, float)):
            raise ConfigError(f"{where}: origin must be a wall-clock time in seconds")
        config.origin = float(data["origin"])
    for key in ("listen", "connect"):
        if key in data:
            value = data[key]
            if not isinstance(value, list) or not all(isinstance(e, str) for e in value):
                raise ConfigError(f"{where}: {key} must be a list of endpoints such as \"tcp/127.0.0.1:0\"")
            setattr(config, key, list(value))
    for key, what in (("inputs", "keys"), ("readers", "node paths")):
        value = data.get(key, {})
        if not isinstance(value, dict) or not all(
                isinstance(k, str) and isinstance(v, list) and all(isinstance(e, str) for e in v)
                for k, v in value.items()):
            raise ConfigError(f"{where}: {key} must map \"channel\" or \"channel/index\" to a list of {what}")
        setattr(config, key, {k: list(v) for k, v in value.items()})
    if "policy" in data:
        if data["policy"] not in ("eager", "latest", "random"):
            raise ConfigError(f"{where}: policy must be \"eager\", \"latest\" or \"random\"")
        config.policy = data["policy"]
    if "seed" in data:
        if not isinstance(data["seed"], int) or isinstance(data["seed"], bool):
            raise ConfigError(f"{where}: seed must be an integer")
        config.seed = data["seed"]
    if "zenoh" in data:
        if not isinstance(data["zenoh"], dict):
            raise ConfigError(f"{where}: zenoh must map config paths to values")
        config.zenoh = dict(data["zenoh"])
    if "input_queue" in data:
        value = data["input_queue"]
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ConfigError(f"{where}: input_queue must be a whole number of inputs >= 1 (or null: "
                              f"unbounded), got {value!r}")
        config.input_queue = value
    if data.get("can") is not None:
        can = data["can"]
        if (not isinstance(can, dict) or not isinstance(can.get("bus"), str)
                or not isinstance(can.get("interface"), str) or not isinstance(can.get("options", {}), dict)):
            raise ConfigError(f"{where}: can must be {{\"bus\": NAME, \"interface\": \"socketcan\"|..., "
                              f"\"channel\": ..., \"bitrate\": ..., \"options\": {{...}}}}")
        config.can = dict(can)
    return config
