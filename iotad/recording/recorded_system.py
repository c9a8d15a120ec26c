"""The system a recording holds: its copy of the system file (system.toml, read as a declaration)
or an in-process run's description (system.json); what the delivery check, the plots and
`iotad check` know of the bindings, external inputs and buses of the run they read.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from iotad.kernel.ports import Port
from iotad.launcher.system.declaration import Declaration, parse_declaration

SYSTEM_TOML, SYSTEM_JSON = "system.toml", "system.json"  # the attachments a recording keeps it in
CAN_TX = "can_tx"


def recorded_declaration(recording: Any) -> Declaration | None:
    """The declaration of the system file `recording` keeps (None: it keeps none). Its files are
    not looked up (the copy has no folder); raises `SystemFileError` where the copy is no TOML."""
    data = next((a.data for a in recording.attachments if a.name == SYSTEM_TOML), None)
    if data is None:
        return None
    return parse_declaration(data.decode(errors="replace"), SYSTEM_TOML)


def recorded_bindings(recording: Any) -> list[tuple[Port, Port]]:
    """(source, target) of every binding the recording's system names, as written (families
    unexpanded; an in-process run's nodes without their root's path); [] where it names none."""
    system = recorded_system(recording, expand=False)
    return [] if isinstance(system, str) else list(system.bindings)


@dataclass
class RecordedSystem:
    """What delivery needs of the recorded system file: concrete bindings, external inputs, buses."""

    name: str
    bindings: list[tuple[Port, Port]] = field(default_factory=list)
    external: set[Port] = field(default_factory=set)
    buses: dict[str, list[str]] = field(default_factory=dict)  # bus -> its stations, in order
    bus_nodes: set[str] = field(default_factory=set)          # bus models (virtual time): not stations


def recorded_system(recording: Any, expand: bool = True) -> RecordedSystem | str:
    """The system attached to `recording` (system.toml, or system.json of an in-process run),
    with family bindings expanded by the recorded channel tables (unless not `expand`); or why
    there is none."""
    from iotad.launcher.system.declaration import SystemFileError

    json_text = next((a.data.decode(errors="replace") for a in recording.attachments if a.name == SYSTEM_JSON), None)
    sizes = _channel_sizes(recording.specs)
    name = recording.system or ""
    try:
        declaration = recorded_declaration(recording)
    except SystemFileError as exc:
        return f"the recorded system.toml is not TOML: {exc.errors[0].split(': not valid TOML: ', 1)[-1]}"
    pairs: list[tuple[Port, Port]] = []
    external: list[Port] = []
    buses: dict[str, list[str]] = {}
    if declaration is not None:
        pairs, external = declaration.bindings, declaration.external
        buses = {bus.name: list(bus.stations) for bus in declaration.buses.values()}
    elif json_text is not None:
        try:
            data = json.loads(json_text)
        except ValueError as exc:
            return f"the recorded system.json is not JSON: {exc}"
        if not isinstance(data, dict):
            return f"the recorded system.json is a {type(data).__name__}, not a JSON object"
        prefix = f"{recording.info.get('root') or data.get('name') or name}/"
        for pair in data.get("bindings", []):
            if isinstance(pair, (list, tuple)) and len(pair) == 2:
                source, target = (_unrooted(Port.parsed(text), prefix) for text in pair)
                if source is not None and target is not None:
                    pairs.append((source, target))
        if isinstance(data.get("external"), list):
            external = [port for port in map(Port.parsed, data["external"]) if port is not None]
    else:
        return "the recording holds no system file (system.toml or system.json), so no bindings"
    out = RecordedSystem(name)
    for source, target in pairs:
        out.bindings += _expand(source, target, sizes) if expand else [(source, target)]
    for port in external:
        members = [port.index] if port.index is not None else _members(sizes.get((port.node, port.channel)))
        out.external.update(port.member(k) for k in members)
    if not buses:  # a virtual run: the bus is a node; station k's can_tx -> bus.tx[k], bus.rx[k] -> can_rx
        found: dict[str, dict[int, str]] = {}
        for source, target in out.bindings:
            if source.channel == CAN_TX and target.channel == "tx" and target.index is not None:
                found.setdefault(target.node, {})[target.index] = source.node
        buses = {bus: [stations[k] for k in sorted(stations)] for bus, stations in found.items()}
        out.bus_nodes = set(buses)
    out.buses = buses
    return out


def _unrooted(port: Port | None, prefix: str) -> Port | None:
    """`port` with its node's path relative to the run's root composite."""
    if port is None or not port.node.startswith(prefix):
        return port
    return Port(port.node[len(prefix):], port.channel, port.index)


def _channel_sizes(specs: dict[str, dict]) -> dict[tuple[str, str], int | None]:
    out: dict[tuple[str, str], int | None] = {}
    for node, spec in specs.items():
        for entry in (spec.get("channels") or []) if isinstance(spec, dict) else []:
            if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                size = entry.get("size")
                out[(node, entry["name"])] = size if isinstance(size, int) else None
    return out


def _members(size: int | None) -> list[int | None]:
    return [None] if size is None else list(range(size))


def _expand(source: Port, target: Port, sizes: dict) -> list[tuple[Port, Port]]:
    """A family bound to a family binds member to member (docs/system-file.md)."""
    src_size = sizes.get((source.node, source.channel)) if source.index is None else None
    dst_size = sizes.get((target.node, target.channel)) if target.index is None else None
    if src_size is not None and dst_size is not None:
        return [(source.member(k), target.member(k)) for k in range(min(src_size, dst_size))]
    return [(source, target)]
