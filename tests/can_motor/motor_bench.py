"""Helpers for the CAN motor node's tests (a module with its own name: `from conftest import` would
find another folder's conftest when folders run together): frames built byte by byte with `struct` (independent of
iotad.can.odrive, so that a codec bug cannot hide a node bug), a motor in an engine in virtual time,
and readers of what it sent."""
from __future__ import annotations

import math
import struct

from iotad.can.frame import Frame
from iotad.kernel.engine import Engine
from nodes.can_motor import CanMotor

TAU = 2 * math.pi

# Command ids of ODrive CAN Simple (firmware 0.6), as the protocol documentation lists them.
HEARTBEAT, ESTOP, GET_ERROR, SET_AXIS_STATE, GET_ENCODER_ESTIMATES = 0x01, 0x02, 0x03, 0x07, 0x09
SET_CONTROLLER_MODE, SET_INPUT_POS, SET_INPUT_VEL, SET_INPUT_TORQUE, SET_LIMITS = 0x0B, 0x0C, 0x0D, 0x0E, 0x0F
SET_TRAJ_VEL_LIMIT, SET_TRAJ_ACCEL_LIMITS, SET_TRAJ_INERTIA = 0x11, 0x12, 0x13
GET_IQ, GET_TEMPERATURE, GET_BUS_VOLTAGE_CURRENT, CLEAR_ERRORS = 0x14, 0x15, 0x17, 0x18
SET_POS_GAIN, SET_VEL_GAINS, GET_TORQUES = 0x1A, 0x1B, 0x1C
CLOSED_LOOP, IDLE = 8, 1

THREE_JOINTS = [
    {"name": "shoulder", "node_id": 1},
    {"name": "elbow", "node_id": 2, "direction": -1, "gear_ratio": 9.0, "offset": 0.5,
     "position_min": -2.0, "position_max": 2.0, "velocity_limit": 2.0, "out_of_range": "clamp"},
    {"name": "wrist", "node_id": 5, "position_min": -1.0, "position_max": 1.0},
]


def can(node: int, cmd: int, data: bytes = b"", *, rtr: bool = False, dlc: int | None = None,
        extended: bool = False, ident: int | None = None) -> dict:
    """A canFrame channel value (plain, as a payload holds it)."""
    dlc = len(data) if dlc is None else dlc
    padded = list(data) + [0] * (8 - len(data))
    return {"id": (node << 5 | cmd) if ident is None else ident, "extended": extended, "rtr": rtr,
            "dlc": dlc, "data": padded}


def heartbeat(node: int, state: int = CLOSED_LOOP, error: int = 0, procedure: int = 0, done: bool = False) -> dict:
    return can(node, HEARTBEAT, struct.pack("<IBBBx", error, state, procedure, int(done)))


def encoder(node: int, turns: float, turns_per_second: float = 0.0) -> dict:
    return can(node, GET_ENCODER_ESTIMATES, struct.pack("<ff", turns, turns_per_second))


def f32(value: float) -> float:
    """`value` as the float32 a frame carries."""
    return struct.unpack("<f", struct.pack("<f", value))[0]


def setpoints(n: int, position=None, velocity_ff=None, torque_ff=None) -> dict:
    return {"position": list(position or [0.0] * n), "velocity_ff": list(velocity_ff or [0.0] * n),
            "torque_ff": list(torque_ff or [0.0] * n)}


class Bench:
    """A CanMotor alone in an engine in virtual time; the test plays the bus."""

    def __init__(self, joints=None, **params):
        params.setdefault("keepalive", 0.0)  # off unless a test is about them: they add frames
        params.setdefault("arm_hold", 0.0)
        self.motor = CanMotor("motor", joints=THREE_JOINTS if joints is None else joints, **params)
        self.n = len(self.motor.joint_map)
        self.engine = Engine(self.motor)

    def post(self, channel: str, value, t: float) -> None:
        self.engine.post(None, channel, value, t=t)

    def hear(self, t: float, *frames: dict) -> None:
        for frame in frames:
            self.post("can_rx", frame, t)

    def run(self, until: float) -> list[dict]:
        return self.engine.run(until=until)

    def events(self, action: str, kind: str = "output", since: float = -1.0) -> list[dict]:
        return [e for e in self.engine.trace if e["action"] == action and e["kind"] == kind and e["t"] >= since]

    def sent(self, since: float = -1.0, until: float = math.inf) -> list[tuple[float, int, bool, bytes]]:
        """(t, id, rtr, data) of every frame sent, in order."""
        out = []
        for e in self.events("can_tx", since=since):
            if e["t"] <= until:
                v = e["value"]
                out.append((e["t"], v["id"], v["rtr"], bytes(v["data"][:v["dlc"]])))
        return out

    def status(self, joint: int | None = None, event: str | None = None) -> list[dict]:
        return [dict(e["value"], t=e["t"]) for e in self.events("joint_status")
                if (joint is None or e["index"] == joint) and (event is None or e["value"]["event"] == event)]

    def violations(self) -> list[dict]:
        return [e for e in self.engine.trace if e["kind"] == "violation"]

    def arm_all(self, t: float = 0.05) -> None:
        """Answer the arming sequence: every axis reports closed loop at `t`."""
        for joint in self.motor.joint_map:
            self.hear(t, heartbeat(joint.node_id))
        self.run(t)

    def final_frames(self) -> list[tuple[int, bool, bytes]]:
        """(id, rtr, data) of what the node host sends on the bus as the node stops."""
        frames = [Frame.from_value(value) for value in self.motor.final_can_frames()]
        return [(frame.id, frame.rtr, frame.data) for frame in frames]
