"""A whole system file as one composite IOTA, for one process in virtual time (`iotad run
--virtual`): every node instantiated as its node host would, the file's bindings as the
composite's, and each `[[can]]` bus as the modelled bus (`iotad.can.burst_bus.BurstCanBus`, or
`iotad.can.virtual_bus.CanBus` for recording format 1) with
station k's can_tx -> tx[k] and rx[k] -> can_rx. Nothing else differs from the real-time run,
which is the point: the same IOTAs, the same channels, the same recording format."""
from __future__ import annotations

from typing import Any

from iotad.can.canopen_ids import canopen_nodes
from iotad.kernel.compose import Composite
from iotad.launcher.system.bus_logger import is_bus_logger
from iotad.launcher.system.system_file import CAN_RX, CAN_TX, System, instantiate


def compose(system: System, recording_format: int = 2) -> Composite:
    """The system as one composite named after it; raises what instantiating a node raises.
    `recording_format` 2 models each bus as `iotad.can.burst_bus.BurstCanBus` (frames in bursts),
    1 as `CanBus` (a firing and an event per frame and receiver), as recordings of format 1 have it."""
    from iotad.can.burst_bus import CAN_TX_BURST, TX_BURST, TX_BURSTS, BurstCanBus, BurstCanopenCanBus
    from iotad.can.virtual_bus import CanBus

    # a bus's real-time logger (bus_logger.py) is left out: here the bus model logs its frames,
    # as the [[can]] entry's `log` says (false: no log in either way of running the file)
    built = {node.name: instantiate(node) for node in system.nodes.values() if not is_bus_logger(system, node.name)}
    components: list[Any] = list(built.values())
    binds = [(str(b.source), str(b.target)) for b in system.bindings]
    for bus in system.buses.values():
        params = dict(stations=len(bus.stations), bitrate=bus.bitrate, log_frames=bus.log)
        # a bus with CiA 402 stations logs each frame by family (CANopen or CAN Simple); one of
        # ODrives only stays the plain model, so its recordings are what they were
        canopen = canopen_nodes(system.nodes[station].params for station in bus.stations if station in system.nodes)
        if canopen:
            from iotad.can.canopen_frame_log import CanopenCanBus
            model = CanopenCanBus if recording_format == 1 else BurstCanopenCanBus
            components.append(model(bus.name, canopen=sorted(canopen), **params))
        else:
            components.append((CanBus if recording_format == 1 else BurstCanBus)(bus.name, **params))
        by_name = {getattr(c, "instance_name", None): c for c in components}
        for k, station in enumerate(bus.stations):
            if hasattr(built.get(station), "can_bus_name"):  # a station that names its bus in what it reports
                built[station].can_bus_name = bus.name
            binds.append((f"{station}.{CAN_TX}", f"{bus.name}.tx[{k}]"))
            binds.append((f"{bus.name}.rx[{k}]", f"{station}.{CAN_RX}"))
            # a station that queues an instant's frames as one output (iotad.can.burst_bus)
            node = by_name.get(station)
            spec = getattr(node, "iota_spec", None)
            if spec is not None and TX_BURSTS in spec.params and TX_BURSTS not in system.nodes[station].params:
                # a station that can send either way (the motor node, the simulated drives) bursts
                # where the bus takes bursts, as its node host has it send on a real bus
                setattr(node, TX_BURSTS, recording_format != 1)
            if node is not None and CAN_TX_BURST in getattr(spec, "channels", {}) and getattr(node, TX_BURSTS, True):
                if recording_format == 1:
                    raise ValueError(f"{station} sends frames in bursts ({CAN_TX_BURST}), which recording "
                                     "format 1's bus cannot take: run it in format 2")
                binds.append((f"{station}.{CAN_TX_BURST}", f"{bus.name}.{TX_BURST}[{k}]"))
    return Composite(system.name, *components, bind=binds)
