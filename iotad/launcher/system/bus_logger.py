"""The bus logger of each `[[can]]` bus in real time: an implicit node named after the bus.

In virtual time the modelled bus (`iotad.can.virtual_bus.CanBus`) logs every frame it carries
on `iota/<system>/<bus>/frames`. In real time the bus is python-can's, and nothing but its
stations would see it, each only from its own side. So a checked system gets one more node per
bus (unless the bus says `log = false`): `iotad.can.frame_log.BusLogger`, named after the bus
(a name no node may take), whose node host opens the same bus listen-only (no `can_tx`; SocketCAN
hands it every other socket's frames) and which records the frames it hears in bursts (recording
format 2), read back as `frames`.

Being an ordinary node is the point: the launcher starts, supervises and restarts it (restart
"on-failure"), the status table and `iotad ls` show it, access control lets it publish its own
keys, the recorder records its output like any other, and `iotad check` (delivery: `can BUS:
STATION -> (bus)`), `iotad info` and `iotad candump` read the topic as they read a virtual run's.
It is not in the system file the recording keeps: `iotad run --virtual` (`in_process.compose`)
leaves it out, the bus model logs there.
"""
from __future__ import annotations

from typing import Any

from iotad.launcher.system.declaration import LOGGER_REF  # noqa: F401 - the logger's class, as this module names it

# The logger nodes themselves are added where the system file is parsed (a parse step:
# `declaration._Parser.add_bus_loggers`), so every reader of a declaration sees them.


def is_bus_logger(system: Any, node: str) -> bool:
    """Whether `node` is the implicit logger of a bus (not a node of the system file)."""
    spec = system.nodes.get(node)
    return spec is not None and spec.bus_logger


def logger_port_config(bus: Any) -> dict[str, Any]:
    """The node host's `can` config of a bus's logger: the bus's, listen-only (it sends nothing)."""
    return dict(bus.port_config(), listen_only=True)
