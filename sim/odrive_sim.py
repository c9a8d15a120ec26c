"""`SimulatedOdrives`: an IOTA of simulated ODrive axes on a CAN bus, one per joint of a PyBullet world.

    can_rx  (input, canFrame, switching 0)   frames from the bus: commands and remote requests
    can_tx  (output, canFrame, switching 0)  answers, and the cyclic Heartbeat and encoder estimates
    step    (internal, every `step_period`)  one control step of every axis, then one world step

The world (`world`, `world_options`) is opened when the IOTA is built, before its engine starts:
opening it in a firing would make that firing and every action due meanwhile late by the
0.1-0.3 s a URDF takes to load. It is registered under `world_key` (default: the instance name)
for sensor IOTAs of the same process (`sim.worlds.find_world`); `close()` releases it.

Each `step`: the world advances one step, then every axis reads its joint, runs its cascaded loop
and gives the joint a torque for the next step (None while IDLE: the world's brake or coast).
Torque, not PyBullet's position or velocity motors, because the cascade is what is simulated: the
ODrive's position and velocity loops with their gains, limits and integrator, and the torque they
end in (docs/simulation.md). The axes keep their own time, `step_period` per step, so in virtual
time it is the engine's time exactly. In real time every firing is a little late (the wake-up, the
other firings of the process), and each step's window starts at the late firing before it: at
240 Hz that lateness added up to a world 14 % slower than the wall clock on a busy machine, and
the conveyor's picks, timed from what vision saw, all missed. So a step takes as many physics steps
as the firing's instant says are due since the first step, up to `max_catch_up` (the rest is
given up: the world falls behind rather than freezing the node), and no more than fit in
`catch_up_time` of the wall clock (the rest stays due for the next firing): frames that come
while a firing runs wait for its end, and a whole catch-up of 24 steps on a loaded machine (80 ms)
would leave the SYNCs of CiA 402 drives unanswered past the motor node's TPDO timeout. In virtual
time the firings are on period and that is always one. Steps and cyclic frames may come up to `timing_slack` late
before that is a deadline miss; eager virtual time fires them at the window's start, exactly on
period.

Units. CAN carries the axis's side: turns, turns/s, motor Nm. An axis maps its joint as
`turns = gear * joint_rad / (2 pi)` and `joint_torque = gear * motor_torque`, gear 1 unless the
`gear` param says otherwise; direction and offset of a joint map belong to the CAN motor node.

Cyclic messages: axis k of N sends its Heartbeat every `heartbeat_period` and its encoder
estimates every `encoder_period`, the axes staggered by period/N (independent controllers are not
in phase), so one can_tx action per message kind walks through the axes.
"""
from __future__ import annotations

import math
import time
from collections import deque
from typing import Any

from iotad import Input, Internal, Iota, Output, Param
from iotad.can.burst_bus import CAN_FRAMES
from iotad.can.frame import CAN_FRAME, Frame, FrameError
from iotad.can.odrive import CONTROL_MODE, INPUT_MODE, decode
from iotad.esprit.runtime import esprit_now

from .odrive_axis import AxisConfig, OdriveAxis
from .worlds import WORLDS, close_world, open_world

TWO_PI = 2.0 * math.pi
GAIN_NAMES = ("pos_gain", "vel_gain", "vel_integrator_gain")
LIMIT_NAMES = ("vel_limit", "current_limit")


class SimulatedOdrives(Iota):
    """Simulated ODrive controllers (firmware 0.6, CAN Simple) driving the joints of one world."""

    world = Param("arm")            # "arm" (xArm6 + gripper), "kuka", "conveyor", "buggy"
    world_options = Param({})       # keyword arguments of the world (seed, belt_speed, ...)
    world_key = Param("")           # registry key of the world in this process; "" = instance name
    node_ids = Param([])            # [id per joint, in joint order] or {joint: id}; [] = 0..N-1
    gear = Param(1.0)               # motor turns per joint turn: a number, [per joint] or {joint: g}
    step_period = Param(1.0 / 240.0)  # s, one control step and one physics step
    heartbeat_period = Param(0.1)   # s, per axis
    encoder_period = Param(0.01)    # s, Get_Encoder_Estimates per axis
    watchdog_timeout = Param(0.08)  # s without a command before an armed axis trips; 0 = off
    control_bandwidth = Param(60.0)  # rad/s: the default gains put the velocity loop here
    gains = Param({})               # {joint: {pos_gain, vel_gain, vel_integrator_gain}} in turn units
    limits = Param({})              # {joint: {vel_limit (turn/s), current_limit (A)}} at power-up
    control_mode = Param("POSITION")   # at power-up: a name, or {joint: name}
    input_mode = Param("PASSTHROUGH")  # at power-up: a name, or {joint: name}
    torque_constant = Param(1.0)    # Nm/A: Set_Limits' Current_Limit times this is the torque limit
    timing_slack = Param(0.005)     # s a step or cyclic frame may be late in real time (window width)
    max_catch_up = Param(24)        # physics steps one late step may take to catch the clock up (0.1 s)
    catch_up_time = Param(0.02)     # s of the wall clock one firing may spend catching up (the rest: next firing)
    # True: the answers waiting at one instant go out as one `can_tx_burst` (one firing); False: one
    # `can_tx` each. `iotad run` sets it where the bus takes bursts (as for the motor node).
    tx_bursts = Param(False)

    can_rx = Input(CAN_FRAME, switching=0)
    can_rx_burst = Input(CAN_FRAMES, switching=0)  # the frames its port received together (real time), in order
    can_tx = Output(CAN_FRAME, switching=0)
    can_tx_burst = Output(CAN_FRAMES, switching=0)  # with tx_bursts: the answers of an instant, in order
    step = Internal(switching=0)

    def init(self):
        _check_params(self)
        self.plant = None           # the world
        self.axes: list[OdriveAxis] = []
        self.by_node: dict[int, OdriveAxis] = {}
        self.driven: list[tuple[int, OdriveAxis, float]] = []  # (joint index, axis, gear)
        self.joint_names: list[str] = []
        self.outbox: deque = deque()  # CAN_FRAME values waiting to go out, in order
        self.steps = 0
        self.sim_time = 0.0
        self.step_origin = None     # the instant of step 0 on the engine's clock (the first step's)
        self.steps_given_up = 0     # steps a late firing was owed beyond max_catch_up (real time)
        self.wall_clock = time.perf_counter  # what a firing's catch-up is timed by (a test may stand in)
        self.next_heartbeat = 0
        self.next_encoder = 0
        self.frames_ignored = 0     # frames for none of our axes, or not understood
        self.last_ignored = ""
        self._open()

    # ------------------------------------------------------------------ actions
    @can_rx.input
    def received(self, value):
        self._receive(value)

    @can_rx_burst.input
    def received_together(self, frames):
        for value in frames:
            self._receive(value)

    @step.action(within=(lambda self: self.step_period, lambda self: self.step_period + self.timing_slack))
    def stepped(self):
        self._catch_up(esprit_now())

    @property
    def clock_time(self) -> float:
        """The world's time on the engine's clock: what a sensor output should stamp, so that a
        reader can compare it with its own now(). The world's own time (`sim_time`, steps times
        `step_period`) starts at 0 with the first step, the engine's clock at the launch: in real
        time they differ by the seconds the nodes took to come up (4 s for the conveyor)."""
        return (self.step_origin or 0.0) + self.sim_time

    def _catch_up(self, now: float) -> None:
        """The physics steps due at `now`: one on period, more after a late firing (the module's
        docstring says why)."""
        dt = self.step_period
        if self.step_origin is None:
            # to the microsecond: the engine's time grid puts a virtual run's first step a hair
            # past `step_period`, and its stamps stay exact multiples of the step this way
            self.step_origin = round(now - dt, 6)
        due = math.floor((now - self.step_origin) / dt + 0.5) - self.steps
        if due > self.max_catch_up:
            self.steps_given_up += due - self.max_catch_up
            self.step_origin += (due - self.max_catch_up) * dt
            due = self.max_catch_up
        # the steps due, but within `catch_up_time` of the wall clock: the frames that come while
        # this firing runs wait for its end (a SYNC's TPDOs, a command that feeds a watchdog): the
        # arm's step costs 1.1 ms (load 11), and 24 of them on a third of a core are 80 ms, past
        # the motor node's TPDO timeout (3 SYNCs, 60 ms). What is left stays due: the next firing.
        started = self.wall_clock()
        for taken in range(max(1, due)):
            if taken and self.wall_clock() - started >= self.catch_up_time:
                break
            self._step()

    # A deadline on every output: a spec that allowed any delay would let a legal schedule (the
    # random policy's, `--seed`) fall behind without limit and still pass `iotad check`.
    @can_tx.action(value=lambda self: self.outbox[0], when=lambda self: len(self.outbox) > 0 and not self.tx_bursts,
                   within=(0, "timing_slack"))
    def answered(self):
        self.outbox.popleft()

    # The same answers in the same order, all those waiting in one firing (CiA 402: every drive's
    # TPDOs of a SYNC); the bus queues them as posted one by one at this instant.
    @can_tx_burst.action(value=lambda self: list(self.outbox), when=lambda self: self.tx_bursts and len(self.outbox) > 0,
                         within=(0, "timing_slack"))
    def answered_all(self):
        self.outbox.clear()

    # (`when`: a subclass may drive no ODrive axis at all, sim/cia402_sim.py)
    @can_tx.action(value=lambda self: self.axes[self.next_heartbeat].heartbeat().to_value(),
                   when=lambda self: len(self.axes) > 0,
                   within=(lambda self: self.heartbeat_period / len(self.axes),
                           lambda self: self.heartbeat_period / len(self.axes) + self.timing_slack))
    def heartbeat(self):
        self.next_heartbeat = (self.next_heartbeat + 1) % len(self.axes)

    @can_tx.action(value=lambda self: self.axes[self.next_encoder].encoder_estimates().to_value(),
                   when=lambda self: len(self.axes) > 0,
                   within=(lambda self: self.encoder_period / len(self.axes),
                           lambda self: self.encoder_period / len(self.axes) + self.timing_slack))
    def encoder_estimates(self):
        self.next_encoder = (self.next_encoder + 1) % len(self.axes)

    # ------------------------------------------------------------------ the work
    def _open(self) -> None:
        options = dict(self.world_options)
        options.setdefault("time_step", self.step_period)
        key = self.world_key or self.instance_name
        plant = open_world(key, self.world, **options)
        try:
            self._make_axes(plant)
        except Exception:
            close_world(key, plant)  # a bad joint map must not leave the world open under its key
            raise
        self.plant = plant

    def _make_axes(self, plant) -> None:
        names = list(plant.joint_names)
        node_of = _node_ids(self.node_ids, names)
        gear_of = _per_joint(self.gear, names, "gear")
        inertias, efforts, speeds = plant.joint_inertias(), plant.effort_limits(), plant.velocity_limits()
        positions, velocities = plant.read_joints()
        axes, driven = [], []
        for index, name in enumerate(names):
            if name not in node_of:
                continue
            gear = gear_of[name]
            config = self._axis_config(name, gear, inertias[index], efforts[index], speeds[index])
            axis = OdriveAxis(node_of[name], config)
            scale = gear / TWO_PI
            axis.update(positions[index] * scale, velocities[index] * scale, 0.0, self.step_period)
            axes.append(axis)
            driven.append((index, axis, gear))
        unknown = (set(self.gains) | set(self.limits)) - set(names)
        if unknown:
            raise ValueError(f"gains/limits name joints the world does not have: {sorted(unknown)}; it has {names}")
        self.axes, self.driven, self.joint_names = axes, driven, names
        self.by_node = {axis.node_id: axis for axis in axes}

    def _axis_config(self, joint: str, gear: float, inertia: float, effort: float, speed: float) -> AxisConfig:
        # the loop is tuned to the inertia the motor sees: J / gear^2, in Nm per turn/s^2
        motor_inertia = inertia / (gear * gear) * TWO_PI
        bandwidth = self.control_bandwidth
        values = dict(pos_gain=bandwidth / 4.0, vel_gain=motor_inertia * bandwidth,
                      vel_integrator_gain=motor_inertia * bandwidth * bandwidth / 4.0,
                      vel_limit=speed * gear / TWO_PI, current_limit=effort / gear / self.torque_constant)
        values.update(self.gains.get(joint, {}))
        values.update(self.limits.get(joint, {}))
        return AxisConfig(**values, inertia=motor_inertia, torque_constant=self.torque_constant,
                          watchdog_timeout=self.watchdog_timeout,
                          control_mode=CONTROL_MODE[_for_joint(self.control_mode, joint, "POSITION")],
                          input_mode=INPUT_MODE[_for_joint(self.input_mode, joint, "PASSTHROUGH")])

    def _step(self) -> None:
        plant, dt = self.plant, self.step_period
        plant.step()
        self.steps += 1
        self.sim_time = now = self.steps * dt
        positions, velocities = plant.read_joints()
        torques: list[float | None] = [None] * len(positions)
        for index, axis, gear in self.driven:
            scale = gear / TWO_PI
            torque = axis.update(positions[index] * scale, velocities[index] * scale, now, dt)
            if torque is not None:
                torques[index] = torque * gear
        plant.apply_torques(torques)

    def _receive(self, value: Any) -> None:
        try:
            message = decode(Frame.from_value(value), as_axis=True)  # as lenient as the firmware
        except FrameError as exc:
            return self._ignored(str(exc))
        axis = self.by_node.get(message.node_id)
        if axis is None:
            return self._ignored(f"node {message.node_id} is none of ours")  # another device's traffic
        for frame in axis.handle(message, self.arrival_time()):
            self.outbox.append(frame.to_value())

    def arrival_time(self) -> float:
        """When a frame taken now reached the axes, on the world's timeline: the engine's clock,
        not `sim_time`. A real drive hears a frame when the bus brings it; this process, stalled
        (a loaded machine), takes the frames that came meanwhile only when it wakes, when its
        world's time still is that of the last step before the stall, and the catch-up then
        advances it past them: stamped with `sim_time`, every frame the host sent on time during
        a 0.1 s stall looked 0.1 s old and the watchdog (80 ms) tripped every axis (the conveyor
        split over three hosts lost its arm so: docs/conveyor.md). Never before the last step."""
        if self.step_origin is None:
            return self.sim_time
        return max(self.sim_time, esprit_now() - self.step_origin)

    def _ignored(self, why: str) -> None:
        self.frames_ignored += 1
        self.last_ignored = why

    def axis(self, joint: str) -> OdriveAxis:
        """The axis driving `joint` (for tests and tools)."""
        for index, axis, _ in self.driven:
            if self.joint_names[index] == joint:
                return axis
        raise KeyError(f"no axis drives joint {joint!r}; driven: {[self.joint_names[i] for i, _, _ in self.driven]}")

    def can_node_ids(self) -> tuple[str, dict[int, str]]:
        """("device", {node id: joint}): the ids this station answers to on its bus (the system
        file's check refuses two stations answering one id)."""
        return "device", {axis.node_id: self.joint_names[index] for index, axis, _ in self.driven}

    def close(self) -> None:
        """Close the world (its PyBullet client)."""
        if self.plant is not None:
            close_world(self.world_key or self.instance_name, self.plant)
            self.plant = None


# ---------------------------------------------------------------------- params
def _check_params(iota: SimulatedOdrives) -> None:
    """Clear errors for bad params at build time (what `iotad run --check` reports)."""
    if iota.world not in WORLDS:
        raise ValueError(f"world {iota.world!r} is not one of {', '.join(WORLDS)}")
    for name in ("step_period", "heartbeat_period", "encoder_period", "control_bandwidth", "torque_constant",
                 "timing_slack", "catch_up_time"):
        value = getattr(iota, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or not math.isfinite(value):
            raise ValueError(f"{name} must be a number > 0, got {value!r}")
    if isinstance(iota.max_catch_up, bool) or not isinstance(iota.max_catch_up, int) or iota.max_catch_up < 1:
        raise ValueError(f"max_catch_up must be a whole number of steps >= 1, got {iota.max_catch_up!r}")
    if isinstance(iota.watchdog_timeout, bool) or not isinstance(iota.watchdog_timeout, (int, float)) \
            or not iota.watchdog_timeout >= 0:
        raise ValueError(f"watchdog_timeout must be a number >= 0 s (0 = off), got {iota.watchdog_timeout!r}")
    for name in ("world_options", "gains", "limits"):
        if not isinstance(getattr(iota, name), dict):
            raise ValueError(f"{name} must be a table, got {getattr(iota, name)!r}")
    if "time_step" in iota.world_options:
        raise ValueError("world_options: time_step is this node's step_period (the world steps when the node "
                         "does); set step_period instead")
    for name, allowed in (("gains", GAIN_NAMES), ("limits", LIMIT_NAMES)):
        for joint, values in getattr(iota, name).items():
            if not isinstance(values, dict) or set(values) - set(allowed) or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and v >= 0 for v in values.values()):
                raise ValueError(f"{name}.{joint}: expected a table of numbers >= 0 named "
                                 f"{', '.join(allowed)}, got {values!r}")
    for name, table in (("control_mode", CONTROL_MODE), ("input_mode", INPUT_MODE)):
        value = getattr(iota, name)
        for mode in (value.values() if isinstance(value, dict) else [value]):
            if mode not in table:
                raise ValueError(f"{name} {mode!r} is not one of {', '.join(table)}")
    if not isinstance(iota.node_ids, (list, dict)):
        raise ValueError(f"node_ids must be a list (joint order) or a table {{joint = id}}, got {iota.node_ids!r}")


def _node_ids(node_ids: list | dict, names: list[str], what: str = "node_ids", first: int = 0,
              last: int = 0x3F) -> dict[str, int]:
    """{joint: id} from a list in joint order or a table; [] numbers every joint from `first`."""
    if isinstance(node_ids, dict):
        unknown = set(node_ids) - set(names)
        if unknown:
            raise ValueError(f"{what} names joints the world does not have: {sorted(unknown)}; it has {names}")
        mapping = dict(node_ids)
    elif not node_ids:
        mapping = {name: first + k for k, name in enumerate(names)}
    elif len(node_ids) != len(names):
        raise ValueError(f"{what} has {len(node_ids)} ids for {len(names)} joints {names}")
    else:
        mapping = dict(zip(names, node_ids))
    ids = list(mapping.values())
    for node in ids:
        if isinstance(node, bool) or not isinstance(node, int) or not first <= node <= last:
            raise ValueError(f"node id {node!r} is not {first}..{last}")
    if len(set(ids)) != len(ids):
        raise ValueError(f"node ids must be distinct, got {mapping}")
    if not mapping:
        raise ValueError(f"{what} leaves no joint with an axis")
    return mapping


def _per_joint(value: Any, names: list[str], what: str) -> dict[str, float]:
    if isinstance(value, dict):
        unknown = set(value) - set(names)
        if unknown:
            raise ValueError(f"{what} names joints the world does not have: {sorted(unknown)}")
        out = {name: value.get(name, 1.0) for name in names}
    elif isinstance(value, list):
        if len(value) != len(names):
            raise ValueError(f"{what} has {len(value)} values for {len(names)} joints {names}")
        out = dict(zip(names, value))
    else:
        out = {name: value for name in names}
    for name, g in out.items():
        if isinstance(g, bool) or not isinstance(g, (int, float)) or not g > 0:
            raise ValueError(f"{what} of {name} must be a number > 0, got {g!r}")
    return {name: float(g) for name, g in out.items()}


def _for_joint(value: str | dict, joint: str, default: str) -> str:
    return value.get(joint, default) if isinstance(value, dict) else value
