"""What a launcher is told before it runs, as three frozen objects passed in whole: how to launch
(`LaunchOptions`), what to record (`RecordingOptions`, or None: no recording) and whether to guard
the hub (`AccessOptions`, or None: zenoh's defaults, no authentication). `iotad run` builds them
from its command line (`cli/commands/run.py`); tests build them directly."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable


@dataclass(frozen=True)
class LaunchOptions:
    """How the launcher runs its nodes.

    `host`: run only this host's nodes (None: all). `port`: the hub's port instead of the file's.
    `until`: stop after so many wall-clock seconds, counted from the launch, or (`after_live`)
    from the moment every node is first live: start-up (imports, PyBullet worlds) can take 10-30 s
    in user-mode Linux and would eat the run. `origin`: the wall-clock time that is t=0 for every
    node (None: now, or the hub launcher's). `log_dir`: keep configs and logs there (None: a temp
    folder, removed unless a node failed). `node_argv(config_path)`: a node's command line
    (default `python -m iotad.host CONFIG`; tests pass a stand-in). `console`, `live_table`: the
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
    # folder whose authority key gives each host's agent secret (iotad/host/agent_secret.py)
    hosts: tuple[str, ...] = ()
    certs: str | None = None
    # one host's launcher started by its agent: its own credentials file (IOTAD_CREDENTIALS)
    given: str | None = None

    @classmethod
    def off(cls, why: str) -> "AccessOptions":
        return cls(enabled=False, why_off=why)


__all__ = ["AccessOptions", "LaunchOptions", "RecordingOptions"]
