"""Each host's own recording of a run spread over hosts: its file's name, the endpoint its recorder
reaches the host's launcher at, and what the file says of itself (for `iotad merge`).

The hub's launcher records what reaches the hub; what a host's nodes do while the hub is out of
reach reaches only that host. So every other host's launcher records too, on its own machine: its
recorder is a client of that launcher's own session (which every node of the host also connects
to), never of the hub, so that a cut link to the hub loses nothing of the host's events. Its
file is the hub's `-o` path with the host's name before `.mcap` (`split.mcap` -> `split.arm.mcap`),
a relative one counted from the agent's working folder (docs/hosts.md, "The recording"); a
restarted recorder goes on in `split.arm_1.mcap`, which the host's launcher announces to the hub,
so that the run's `join them with: iotad merge ...` line names every file.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from iotad.node_host.transport import free_port, reachable


def host_recording_path(path: str | Path, host: str) -> Path:
    """Where host `host` records the run the hub records to `path`."""
    path = Path(path)
    suffix = path.suffix if path.suffix == ".mcap" else ""
    stem = path.name[:-len(suffix)] if suffix else path.name
    return path.with_name(f"{stem}.{host}{suffix or '.mcap'}")


def host_files(path: str | Path, host: str, heard: list[str] | None = None) -> list[Path]:
    """Every file host `host` recorded the run to, as far as the hub knows: its first file
    (`host_recording_path`) and each file its launcher said a restarted recorder went on in
    (`heard`, in order: `split.arm_1.mcap`...)."""
    first = host_recording_path(path, host)
    return [first, *(Path(f) for f in heard or [] if Path(f) != first)]


def join_command(hub_files: list[str | Path], hosts: dict[str, list[Path]]) -> str:
    """The `iotad merge` that joins every file of a run: the hub's (each part, in order), then
    each host's."""
    files = [str(f) for f in hub_files] + [str(f) for files in hosts.values() for f in files]
    return f"iotad merge {' '.join(files)} -o MERGED.mcap"


def pinned(endpoints: list[str]) -> list[str]:
    """`endpoints` with port 0 replaced by a port free now on the same address: a recorder and
    the host's nodes must be told where its launcher listens."""
    out = []
    for endpoint in endpoints:
        protocol, _, address = endpoint.partition("/")
        host, _, port = address.rpartition(":")
        if port == "0" and protocol in ("tcp", "tls") and host and not host.startswith("["):
            try:
                endpoint = f"{protocol}/{host}:{free_port(host)}"
            except OSError:
                pass  # an address not on this machine: zenoh says so when it listens
        out.append(endpoint)
    return out


def local_endpoints(listen: list[str]) -> list[str]:
    """Where processes on this host reach a launcher listening on `listen` (pinned)."""
    return [reachable(e) for e in listen if not e.rpartition(":")[2] == "0"]


def run_info(host: str, hub: bool, origin: float, clock: dict[str, Any] | None = None) -> dict[str, Any]:
    """The `run` metadata of a host's recording: whose it is, the run's origin on the hub's clock
    (the same in every file of one run), and the host's clock offset to the hub as measured at
    start (`clock`: offset, bound, samples, measured_ns on the host's clock)."""
    info: dict[str, Any] = {"host": host, "hub": hub, "origin": origin}
    if clock is not None:
        info["clock"] = clock
    return info


__all__ = ["host_files", "host_recording_path", "join_command", "local_endpoints", "pinned", "run_info"]
