"""The bus logger of each `[[can]]` bus in real time: an implicit node named after the bus.

In virtual time the modelled bus (`iotad.can.virtual_bus.CanBus`) logs every frame it carries
on `iota/<system>/<bus>/frames`. In real time the bus is python-can's, and nothing but its
stations would see it, each only from its own side. So a checked system gets one more node per
bus (unless the bus says `log = false`): `iotad.can.frame_log.BusLogger`, named after the bus
(a name no node may take), whose node host opens the same bus listen-only (no `can_tx`; SocketCAN
hands it every other socket's frames) and which publishes each frame it hears on `frames`.

Being an ordinary node is the point: the launcher starts, supervises and restarts it (restart
"on-failure"), the status table and `iotad ls` show it, access control lets it publish its own
keys, the recorder records its output like any other, and `iotad check` (delivery: `can BUS:
STATION -> (bus)`), `iotad info` and `iotad candump` read the topic as they read a virtual run's.
It is not in the system file the recording keeps: `iotad run --virtual` (`in_process.compose`)
leaves it out, the bus model logs there.
"""
from __future__ import annotations

from typing import Any

LOGGER_REF = "iotad.can.frame_log:BusLogger"
LAG = 0.1  # seconds a frame may wait in the logger before its log entry is late (a deadline miss)


def add_bus_loggers(system: Any) -> None:
    """Add the logger node of every bus of `system` that logs (`CanBusSpec.log`)."""
    from iotad.launcher.system_file import NodeSpec

    for bus in system.buses.values():
        if not getattr(bus, "log", True) or bus.name in system.nodes:
            continue
        hosts = [system.nodes[s].host for s in bus.stations if s in system.nodes]
        system.nodes[bus.name] = NodeSpec(
            name=bus.name, entry=f"{bus.entry}'s bus logger", source={"kind": "python", "ref": LOGGER_REF},
            params={"bitrate": bus.bitrate, "lag": LAG / system.time_unit},  # lag: in the system's time unit
            host=next((h for h in hosts if h is not None), None))


def is_bus_logger(system: Any, node: str) -> bool:
    """Whether `node` is the implicit logger of a bus (not a node of the system file)."""
    spec = system.nodes.get(node)
    return node in system.buses and spec is not None and spec.source.get("ref") == LOGGER_REF


def logger_port_config(bus: Any) -> dict[str, Any]:
    """The node host's `can` config of a bus's logger: the bus's, listen-only (it sends nothing)."""
    return dict(bus.port_config(), listen_only=True)
