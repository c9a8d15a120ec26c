"""`[[can]] interface = "env"`: the bus is whatever the environment names, so that one system file
runs unchanged on every CAN tier (`python -m iotad.can.tiers run -- iotad run FILE` sets
IOTAD_CAN_INTERFACE and IOTAD_CAN_CHANNEL: vcan0, or a multicast group) and on a real bus
(`IOTAD_CAN_INTERFACE=socketcan IOTAD_CAN_CHANNEL=can0 iotad run FILE`).

The launcher resolves it when it writes each node's config (the node's log then names the real
bus), and refuses to start, saying how, where the environment names no bus. `--check` and
`--virtual` need no bus, so they take the file as it is.
"""
from __future__ import annotations

from typing import Any

from iotad.can.bus import ENV, ENV_CHANNEL, ENV_INTERFACE, env_bus


def resolved(interface: str, channel: str | None) -> tuple[str, str | None]:
    """The (interface, channel) to open: the environment's bus for `env`, else as given."""
    if interface == ENV:
        found = env_bus()
        if found is not None:
            return found
    return interface, channel


def unresolved(system: Any, host: str | None = None) -> str | None:
    """Why the buses of the nodes `host` runs cannot be opened here, or None."""
    names = sorted({bus.name for bus in system.buses.values() if bus.interface == ENV
                    and any(node.host == host or host is None for node in system.nodes.values()
                            if node.name in bus.stations or node.name == bus.name)})
    if not names or env_bus() is not None:
        return None
    return (f"{system.file}: [[can]] {', '.join(names)}: interface = \"{ENV}\" takes the bus from "
            f"{ENV_INTERFACE} and {ENV_CHANNEL}, which are not set; run it with a CAN bus "
            f"(python -m iotad.can.tiers run -- iotad run {system.file} ...), or set them "
            f"({ENV_INTERFACE}=socketcan {ENV_CHANNEL}=can0)")
