"""`SimulatedCia402Drives`: simulated CANopen CiA 402 drives (and, for a mixed bus, ODrive axes) driving a PyBullet world.

The same IOTA as `SimulatedOdrives` (sim/odrive_sim.py: channels, world, steps, timing), with
joints driven by `Cia402Drive`s (sim/cia402_drive.py) at the CANopen node ids of `cia402`, and
by simulated ODrive axes at the ids of `node_ids` where a joint is named there: ODrives and
CiA 402 drives on one bus, each joint one controller.

A CiA 402 drive answers SDOs, PDOs and NMT at once (in `can_rx`) and sends its TPDOs at SYNC; its
heartbeat and its heartbeat-consumer check run in the control step, so both fall on the step
grid (`step_period`): a heartbeat up to one step late, a lost master found within the consumer
time plus one step.
"""
from __future__ import annotations

from typing import Any

from iotad import Param
from iotad.can import canopen as co
from iotad.can.frame import Frame, FrameError

from .cia402_drive import Cia402Drive
from .odrive_axis import OdriveAxis
from .odrive_sim import TWO_PI, SimulatedOdrives, _node_ids, _per_joint


class SimulatedCia402Drives(SimulatedOdrives):
    """CiA 402 drives at `cia402` = {joint: node id 1..127} (a list: joint order; empty: every
    joint, ids 1..N), ODrive axes at `node_ids` = {joint: id} (none by default)."""

    cia402 = Param([])       # {joint: CANopen node id} or [ids in joint order]; [] = every joint, 1..N
    node_ids = Param({})     # ODrive axes for a mixed bus: {joint: id 0..63}; {} = none
    eds = Param("")          # the drives' EDS; "" = iotad/can/data/cia402_drive.eds

    def init(self):
        self.drives: list[Cia402Drive] = []
        self.drive_by_node: dict[int, Cia402Drive] = {}
        super().init()

    def _make_axes(self, plant) -> None:
        names = list(plant.joint_names)
        odrive_of = _node_ids(self.node_ids, names) if self.node_ids else {}
        if not isinstance(self.cia402, (list, dict)):
            raise ValueError(f"cia402 must be a list (joint order) or a table {{joint = id}}, got {self.cia402!r}")
        drive_of = _node_ids(self.cia402, [n for n in names if n not in odrive_of], "cia402", 1, co.NODE_ID_MAX)
        both = set(odrive_of) & set(drive_of)
        if both:
            raise ValueError(f"joints {sorted(both)} are in both node_ids (ODrive) and cia402")
        gear_of = _per_joint(self.gear, names, "gear")
        inertias, efforts, speeds = plant.joint_inertias(), plant.effort_limits(), plant.velocity_limits()
        positions, velocities = plant.read_joints()
        axes, drives, driven = [], [], []
        eds = self.eds or co.DRIVE_EDS
        for index, name in enumerate(names):
            if name not in odrive_of and name not in drive_of:
                continue
            gear = gear_of[name]
            config = self._axis_config(name, gear, inertias[index], efforts[index], speeds[index])
            scale = gear / TWO_PI
            if name in odrive_of:
                controller = OdriveAxis(odrive_of[name], config)
                axes.append(controller)
            else:
                try:
                    controller = Cia402Drive(drive_of[name], config, eds)
                except ValueError as exc:
                    raise ValueError(f"joint {name}: {exc}") from None
                drives.append(controller)
            controller.update(positions[index] * scale, velocities[index] * scale, 0.0, self.step_period)
            driven.append((index, controller, gear))
        unknown = (set(self.gains) | set(self.limits)) - set(names)
        if unknown:
            raise ValueError(f"gains/limits name joints the world does not have: {sorted(unknown)}; it has {names}")
        self.axes, self.drives, self.driven, self.joint_names = axes, drives, driven, names
        self.by_node = {axis.node_id: axis for axis in axes}
        self.drive_by_node = {drive.node_id: drive for drive in drives}
        self._drain()  # the boot-up messages

    def _receive(self, value: Any) -> None:
        try:
            frame = Frame.from_value(value)
        except FrameError as exc:
            return self._ignored(str(exc))
        if self._is_canopen(frame):
            for drive in self.drives:  # every drive hears the bus (NMT, SYNC, the master's heartbeat)
                drive.handle(frame, self.arrival_time())
            self._drain()
        else:
            super()._receive(value)

    def _is_canopen(self, frame: Frame) -> bool:
        """A frame for the CiA 402 drives: NMT, SYNC, heartbeats, and what is addressed to one of them."""
        if not self.drives or frame.extended:
            return False
        if frame.id in (co.NMT, co.SYNC) or frame.id & 0x780 == co.HEARTBEAT:
            return True
        return frame.id & 0x7F in self.drive_by_node and frame.id & 0x780 in co.SERVICES

    def _step(self) -> None:
        super()._step()
        self._drain()

    def _drain(self) -> None:
        for drive in self.drives:
            if drive.outbox:
                self.outbox.extend(frame.to_value() for frame in drive.outbox)
                drive.outbox.clear()

    def drive(self, joint: str) -> Cia402Drive:
        """The CiA 402 drive of `joint` (for tests and tools)."""
        controller = self.axis(joint)
        if not isinstance(controller, Cia402Drive):
            raise KeyError(f"joint {joint!r} is driven by an ODrive axis, not a CiA 402 drive")
        return controller

    def can_node_ids(self) -> tuple[str, dict[int, str]]:
        """("device", {node id: joint}) of both families."""
        return "device", {controller.node_id: self.joint_names[index] for index, controller, _ in self.driven}
