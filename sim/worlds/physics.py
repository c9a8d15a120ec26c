"""PyBullet clients for the worlds: a DIRECT connection set up the same way everywhere, and boxes.

Every world has its own client (`connect`), so several worlds live in one process and a test
never sees another's bodies. DIRECT: no GUI, no real-time simulation; the world calls
`stepSimulation` itself, which is what makes runs deterministic (docs/simulation.md).
"""
from __future__ import annotations

import pybullet
import pybullet_data


def connect(time_step: float, gravity: float = -9.81) -> int:
    """A fresh DIRECT client with the pybullet_data search path, the time step and gravity set."""
    if not time_step > 0:
        raise ValueError(f"time_step must be > 0 s, got {time_step!r}")
    client = pybullet.connect(pybullet.DIRECT)
    pybullet.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
    pybullet.setTimeStep(time_step, physicsClientId=client)
    pybullet.setGravity(0, 0, gravity, physicsClientId=client)
    return client


def disconnect(client: int) -> None:
    if pybullet.isConnected(physicsClientId=client):
        pybullet.disconnect(physicsClientId=client)


def box(client: int, half_extents, position, rgba=(0.6, 0.6, 0.6, 1.0), mass: float = 0.0,
        collision: bool = True, orientation=(0, 0, 0, 1)) -> int:
    """A box body (static when mass is 0; no collision shape when `collision` is False)."""
    shape = (pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half_extents, physicsClientId=client)
             if collision else -1)
    visual = pybullet.createVisualShape(pybullet.GEOM_BOX, halfExtents=half_extents, rgbaColor=rgba,
                                        physicsClientId=client)
    return pybullet.createMultiBody(baseMass=mass, baseCollisionShapeIndex=shape, baseVisualShapeIndex=visual,
                                    basePosition=position, baseOrientation=orientation, physicsClientId=client)
