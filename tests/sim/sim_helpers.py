"""Shared helpers of the sim tests: messages as an axis receives them, a one-inertia plant in the
axis's units, and simulated controllers in virtual time with frames posted as CAN_FRAME values."""
from __future__ import annotations

import heapq
import math

import pytest

from iotad import Engine
from iotad.kernel.clock import VirtualClock
from iotad.can import odrive
from iotad.can.frame import Frame
from sim.odrive_axis import AxisConfig, OdriveAxis
from sim.odrive_sim import SimulatedOdrives

DT = 1.0 / 240.0
TWO_PI = 2 * math.pi


def command(node: int, name: str, **signals) -> odrive.Message:
    """A host command as the axis sees it: encoded to bytes and decoded again."""
    return odrive.decode(odrive.encode(node, name, **signals))


def poll(node: int, name: str) -> odrive.Message:
    return odrive.decode(odrive.request(node, name))


class Inertia:
    """A motor on an inertia, in turns: J in Nm/(turn/s^2), an optional constant load torque."""

    def __init__(self, inertia: float = 0.01, load: float = 0.0, friction: float = 0.0):
        self.inertia, self.load, self.friction = inertia, load, friction
        self.position = self.velocity = 0.0

    def step(self, torque: float | None, dt: float = DT) -> None:
        torque = (torque or 0.0) + self.load - self.friction * self.velocity
        self.velocity += torque / self.inertia * dt
        self.position += self.velocity * dt


def run(axis: OdriveAxis, plant: Inertia, start: float, seconds: float, feed=None, dt: float = DT) -> list:
    """Step axis and plant from `start` for `seconds`; `feed(t)` may send commands. Torques out."""
    torques = []
    for k in range(round(seconds / dt)):
        t = start + k * dt
        if feed is not None:
            feed(t)
        torque = axis.update(plant.position, plant.velocity, t, dt)
        torques.append(torque)
        plant.step(torque, dt)
    return torques


@pytest.fixture
def armed_axis():
    """Node 3 in closed loop, tuned for a 0.01 Nm/(turn/s^2) inertia, watchdog off."""
    inertia = 0.01
    axis = OdriveAxis(3, AxisConfig(pos_gain=15, vel_gain=inertia * 60, vel_integrator_gain=inertia * 900,
                                    vel_limit=5.0, current_limit=5.0))
    axis.handle(command(3, "Set_Axis_State", Axis_Requested_State=8), 0.0)
    assert axis.armed
    return axis, Inertia(inertia)


class Sim:
    """SimulatedOdrives in an Engine under a virtual clock: post frames, run, read frames back."""

    def __init__(self, **params):
        self.iota = SimulatedOdrives("sim", **params)
        self.engine = Engine(self.iota)

    def post(self, t: float, frame: Frame) -> None:
        self.engine.post(None, "can_rx", frame.to_value(), t=t)

    def send(self, t: float, node: int, name: str, **signals) -> None:
        self.post(t, odrive.encode(node, name, **signals))

    def run(self, until: float) -> None:
        self.engine.run(until=until)

    def sent(self, name: str | None = None, node: int | None = None) -> list[tuple[float, odrive.Message]]:
        """(time, message) of the frames put on can_tx, optionally of one kind and node."""
        out = []
        for event in self.engine.trace:
            if event["action"] == "can_tx" and event["kind"] == "output":
                message = odrive.decode(Frame.from_value(event["value"]))
                if (name is None or message.name == name) and (node is None or message.node_id == node):
                    out.append((event["t"], message))
        return out

    def violations(self) -> list[dict]:
        return [e for e in self.engine.trace if e["kind"] == "violation"]

    def close(self) -> None:
        self.iota.close()


@pytest.fixture
def make_sim():
    sims = []

    def make(**params) -> Sim:
        sim = Sim(**params)
        sims.append(sim)
        return sim

    try:
        yield make
    finally:
        for sim in sims:
            sim.close()


class BusyClock(VirtualClock):
    """Virtual time that also goes by while the process computes (`spend`), as a loaded machine's
    does: an input that arrived meanwhile is taken after, at the time the process gets to it,
    not at its arrival."""

    def spend(self, seconds: float) -> None:
        self._now += seconds

    def wait(self, deadline):
        if self._inbox and self._inbox[0][0] <= max(deadline, self._now):
            t, _, item = heapq.heappop(self._inbox)
            self._now = max(self._now, t)
            return item
        if deadline != float("inf"):
            self._now = max(self._now, deadline)
        return None
