"""System files: which IOTAs run as which processes, how their channels are bound, and where
the hub is. Parsed by `declaration.py` (no IOTA built), then checked whole here before anything starts.

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

import sys
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from iotad.kernel.api import close_iotas
from iotad.kernel.ports import Port, PortSyntaxError
from iotad.launcher.system.declaration import (  # noqa: F401 - the declaration's names, as callers know them here
    DEFAULT_INPUT_QUEUE, LOOPBACK_LISTEN, RESTART_MODES, TABLE_HINT, CanBusSpec, Declaration, HostSpec, NodeDecl,
    SystemFileError, read_declaration)
from iotad.launcher.system.ros2_tables import add_ros2_bridge
from iotad.launcher.system.system_model import (  # noqa: F401 - the model's names, as callers know them here
    Binding, ChannelInfo, NodeSpec, System, channel_table, instantiate, param_names)

CAN_TX, CAN_RX = "can_tx", "can_rx"  # the two channels of a node on a CAN bus
CAN_RX_BURST = "can_rx_burst"  # a station's optional input of the frames its port received together (real time)
PEER_RESTART = "peer_restart"  # an input the node host feeds when a peer restarts (iotad.node_host.peer_restart)


# ---------------------------------------------------------------------------- loading

def load_system(path: str | Path, check: bool = True) -> System:
    """Parse (and by default check) a system file; raises `SystemFileError` listing every problem."""
    return check_system(read_declaration(path), check)


def check_system(declaration: Declaration, check: bool = True) -> System:
    """The system `declaration` declares, checked against its nodes' IOTAs (built here, in this
    process) unless `check` is false; raises `SystemFileError` listing every problem."""
    return _Checker(declaration).check(check)


class _Checker:
    def __init__(self, declaration: Declaration):
        self.declaration, self.errors = declaration, list(declaration.errors)
        self.unbuilt: set[str] = set()  # nodes whose IOTA could not be made: their channels are unknown
        self.can_claims: dict[str, tuple[str, dict[int, str]]] = {}  # node -> its `can_node_ids()`
        self.file = declaration.file

    def error(self, entry: str, message: str) -> None:
        self.errors.append(f"{self.file}: {entry}: {message}")

    def check(self, check: bool) -> System:
        declaration = self.declaration
        system = System(declaration, {name: NodeSpec(node) for name, node in declaration.nodes.items()})
        if check and not self.errors:
            self.load_channels(system)
            self.check_stations(system)
        if check and not self.errors:
            self.check_bindings(system)
            for where, raw in declaration.externals:
                self.check_external(system, raw, where, system.external)
            self.check_allow_pub(system)
            if not self.errors:  # [[ros2]]: the ROS 2 bridge node and its bindings (docs/ros2.md)
                add_ros2_bridge(self, system, list(declaration.ros2))
            if not self.errors:  # an input whose binding failed is not also "unbound"
                self.check_inputs_covered(system)
        if self.errors:
            raise SystemFileError(self.errors)
        return system

    def load_channels(self, system: System) -> None:
        for node in system.nodes.values():
            try:
                with _said_if_slow(f"still building node {node.name}'s IOTA to check it, after {SLOW_BUILD:g} s: "
                                   "its module or init may block (Ctrl-C stops)"):
                    instance = instantiate(node)
                try:
                    node.channels = channel_table(instance)
                    node.param_names = param_names(instance)
                    claims = getattr(instance, "can_node_ids", None)
                    if callable(claims):
                        self.can_claims[node.name] = claims()
                finally:  # built to be read, not run: a simulator's world is not left open
                    close_iotas([instance])
            except Exception as exc:  # noqa: BLE001 - whatever the spec raises is the user's message
                message = str(exc).strip() or type(exc).__name__
                from iotad.kernel.code_fault import fault_where
                where = fault_where(exc)  # the node's own code raised (its init()): at which line
                if where and node.source["kind"] == "python":
                    message = f"{type(exc).__name__}: {message} (at {where})"
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
        try:
            port = Port.parse(text)
        except PortSyntaxError as exc:
            self.error(entry, str(exc))
            return None
        node_name, channel_name, port_index = port.node, port.channel, port.index
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
        if port_index is not None:
            if channel.size is None:
                self.error(entry, f"{node_name}.{channel_name} is not a family; drop the [{port_index}]")
                return None
            if port_index >= channel.size:
                members = f"{channel.size} members (0..{channel.size - 1})" if channel.size else \
                    "no members (its size parameter is 0)"
                self.error(entry, f"index {port_index} is out of range: {node_name}.{channel_name} has {members}")
                return None
        return port, channel

    def check_bindings(self, system: System) -> None:
        senders: dict[Port, list[Binding]] = {}
        for bind in self.declaration.binds:
            entry = bind.entry
            for key in bind.unknown:
                self.error(entry, f"unknown key {key!r} (expected from, to)" + TABLE_HINT.get(key, ""))
            if bind.source is None or bind.target is None:
                self.error(entry, "needs both from = \"node.output\" and to = \"node.input\"")
                continue
            source = self.resolve(system, bind.source, entry, "output")
            target = self.resolve(system, bind.target, entry, "input")
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

    def check_external(self, system: System, raw: Any, where: str, ports: set[Port]) -> None:
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
            ports.update(port.member(k) for k in members)

    def check_allow_pub(self, system: System) -> None:
        """[system.debug] allow_pub = ["node.input", "node.input[k]"]: the inputs `iotad pub` may
        write into when access control is on (docs/access-control.md)."""
        debug = self.declaration.debug
        if debug is None:
            return
        where = "[system.debug]"
        if not debug.table:
            self.error(where, "must be a table: { allow_pub = [\"node.input[k]\", ...] }")
            return
        for key in debug.unknown:
            self.error(where, f"unknown key {key!r} (expected allow_pub)")
        self.check_external(system, debug.allow_pub, f"{where} allow_pub", system.allow_pub)

    # ------------------------------------------------------------ [[can]]
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
        # A joint commanded on a bus of simulated drives that no drive serves never answers: its
        # motor node waits for it forever, and a joint_states that waits for every joint stops
        # the whole robot. Only where the bus's drives are all declared here (a simulated bus):
        # a real drive is no station and is not known to the check.
        served = {node_id for (role, node_id) in claimed if role == "device"}
        if served:
            for (role, node_id), (station, label) in sorted(claimed.items(), key=lambda item: item[0][1]):
                if role == "host" and node_id not in served:
                    self.error(bus.entry, f"{station}: joint {label!r} is commanded on CAN node id {node_id}, "
                                          f"which no simulated drive on bus {bus.name!r} serves (served: "
                                          f"{', '.join(str(i) for i in sorted(served))})")

    def check_inputs_covered(self, system: System) -> None:
        bound = {b.target for b in system.bindings}
        # a station's frames from its bus, one by one or received together (fed by its node host)
        bound |= {Port(station, name, None) for bus in system.buses.values() for station in bus.stations
                  for name in (CAN_RX, CAN_RX_BURST)}
        bound |= {Port(bus, name, None) for bus in system.buses for name in (CAN_RX, CAN_RX_BURST)}  # a bus logger's
        for node in system.nodes.values():
            restart = node.channels.get(PEER_RESTART)
            if restart is not None and restart.direction == "input":
                # fed by the node host (restart notices of its peers), never by a binding
                if restart.size is not None or (restart.type is not None and not hasattr(restart.type, "members")):
                    self.error(node.entry, f"input {PEER_RESTART} (restart notices from the node host) must be "
                                           f"one plain input with no value or an enum of channel names")
                bound.add(Port(node.name, PEER_RESTART, None))
            if Port(node.name, CAN_RX, None) in bound | system.external:
                bound.add(Port(node.name, CAN_RX_BURST, None))  # the same frames, received together
            missing = [str(Port(node.name, channel.name, k)) for channel in node.channels.values()
                       if channel.direction == "input" for k in channel.members()
                       if Port(node.name, channel.name, k) not in bound | system.external]
            if missing:
                shown = ", ".join(missing[:8]) + (f" and {len(missing) - 8} more" if len(missing) > 8 else "")
                self.error(node.entry, f"input(s) {shown} neither bound nor declared external "
                                       f"(add a [[bind]] or external = [\"{missing[0]}\"])")


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
