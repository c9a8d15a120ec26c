"""What a run is told, as frozen objects passed in whole: a host's run as `iotad run` asks it, and
as the hub orders each other host's agent to run its part (`RunOptions`, JSON on the wire); and
what its launcher is told before it runs: how to launch (`LaunchOptions`), what to record
(`RecordingOptions`, or None: no recording) and whether to guard the hub (`AccessOptions`, or
None: zenoh's defaults, no authentication). `run_system.run_real_time` builds the launcher's from
a `RunOptions`; tests build them directly."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable


@dataclass(frozen=True)
class RunOptions:
    """How one host's part of a system runs in real time (`iotad run`'s options, docs there)."""

    host: str | None = None           # the host whose nodes run here (None: the hub's, or all)
    port: int | None = None           # the hub's port instead of the file's (0: any free one)
    until: float | None = None        # wall seconds from the launch (or from every node live)
    after_live: bool = False
    origin: float | None = None       # the run's origin, wall time (a host joining the hub's run)
    log_dir: str | None = None
    plain: bool = False               # plain event lines even on a terminal
    record_to: str | None = None      # the recording (None: a new name under recordings/)
    no_record: bool = False
    force: bool = False
    max_size: int | None = None
    max_duration: float | None = None
    local: bool = False               # every host's nodes on this machine, no agents
    certs: str | None = None
    agent_timeout: float | None = None
    insecure: bool = False
    strict: bool = False      # any violation or a node never live ends the run non-zero

    def to_json(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: Any) -> RunOptions:
        """The options `data` (a run order's) holds; ValueError in one line where it is no such thing."""
        if not isinstance(data, dict):
            raise ValueError("a run's options must be a JSON object")
        fields = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - set(fields))
        if unknown:
            raise ValueError(f"a run's options name unknown option(s) {', '.join(unknown)}")
        for name, value in data.items():
            wanted = {"bool": (bool,), "str | None": (str, type(None)), "int | None": (int, type(None)),
                      "float | None": (int, float, type(None))}[fields[name].type]
            if not isinstance(value, wanted) or (isinstance(value, bool) and bool not in wanted):
                raise ValueError(f"a run's option {name} must be {fields[name].type}, got {value!r}")
        return cls(**data)


@dataclass(frozen=True)
class LaunchOptions:
    """How the launcher runs its nodes.

    `host`: run only this host's nodes (None: all). `port`: the hub's port instead of the file's.
    `until`: stop after so many wall-clock seconds, counted from the launch, or (`after_live`)
    from the moment every node is first live: start-up (imports, PyBullet worlds) can take 10-30 s
    in user-mode Linux and would eat the run. `origin`: the wall-clock time that is t=0 for every
    node (None: now, or the hub launcher's). `log_dir`: keep configs and logs there (None: a temp
    folder, removed unless a node failed). `node_argv(config_path)`: a node's command line
    (default `python -m iotad.node_host CONFIG`; tests pass a stand-in). `console`, `live_table`: the
    status view's. `stop_timeouts`: seconds after SIGINT, then after SIGTERM, before the next."""

    host: str | None = None
    port: int | None = None
    until: float | None = None
    after_live: bool = False
    origin: float | None = None
    log_dir: str | None = None
    node_argv: Callable[[str], list[str]] | None = None
    console: Any = None
    live_table: bool | None = None
    stop_timeouts: tuple[float, float] = (3.0, 2.0)


@dataclass(frozen=True)
class RecordingOptions:
    """Where and how the run is recorded. `path`: the .mcap file (the CLI names and claims it).
    `force`: a continuation file may replace an earlier run's. `max_size`, `max_duration`: split
    the recording into numbered files (`iotad record --max-size/--max-duration`)."""

    path: str
    force: bool = False
    max_size: int | None = None
    max_duration: float | None = None


@dataclass(frozen=True)
class AccessOptions:
    """Access control of the hub (docs/access-control.md): on, or off and why (`--insecure`, a
    system spread over hosts whose links have no certificates), which the launcher says as a
    warning."""

    enabled: bool = True
    why_off: str = ""
    # a system spread over hosts, run through agents: the other hosts, and the certificates'
    # folder whose authority key gives each host's agent secret (iotad/machine/agent_secret.py)
    hosts: tuple[str, ...] = ()
    certs: str | None = None
    # one host's launcher started by its agent: its own credentials file (IOTAD_CREDENTIALS)
    given: str | None = None

    @classmethod
    def off(cls, why: str) -> "AccessOptions":
        return cls(enabled=False, why_off=why)


__all__ = ["AccessOptions", "LaunchOptions", "RecordingOptions"]
