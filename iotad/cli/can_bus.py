"""The CAN bus a command opens (`iotad candump`, `iotad can`): a system file's [[can]] bus, an
interface and channel given, or the tier's bus from the environment (iotad/can/tiers.py)."""
from __future__ import annotations

import argparse

from iotad.can.canopen_ids import canopen_nodes


def live_bus(args: argparse.Namespace):
    """The bus `args` name (a system file and --bus, --interface and --channel, or none: the
    environment's); sets `args.named_canopen` to the CANopen nodes a system file names."""
    from iotad.can.bus import open_bus, open_env_bus
    from iotad.cli import CliError

    if args.source:
        if args.interface or args.channel:
            raise CliError("give a system file or --interface/--channel, not both")
        from iotad.launcher.system.system_file import SystemFileError, load_system

        try:
            system = load_system(args.source)
        except SystemFileError as exc:
            raise CliError(str(exc).splitlines()[0] if str(exc) else "bad system file") from None
        buses = system.buses
        if not buses:
            raise CliError(f"{args.source}: no [[can]] bus")
        if args.bus is None and len(buses) > 1:
            raise CliError(f"{args.source} has buses {', '.join(buses)}: choose one with --bus")
        spec = buses.get(args.bus) if args.bus else next(iter(buses.values()))
        if spec is None:
            raise CliError(f"{args.source}: no [[can]] bus named {args.bus!r} (it has {', '.join(buses)})")
        args.named_canopen = canopen_nodes(node.params for node in system.nodes.values())
        return open_bus(spec.interface, spec.channel, **spec.options)
    if args.bus:
        raise CliError("--bus names a [[can]] bus of a system file: give the file")
    if args.interface:
        return open_bus(args.interface, args.channel)
    if args.channel:
        raise CliError("--channel needs --interface")
    return open_env_bus()
