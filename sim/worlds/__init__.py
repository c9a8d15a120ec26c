"""PyBullet worlds the simulated controllers drive, by name, and the worlds open in this process.

    world = make_world("arm")                 # a Plant: joints to read and drive (plant.py)
    world = open_world("sim", "conveyor", seed=3)   # the same, and findable by key ...
    find_world("sim")                         # ... by sensors composed in the same process

Names: "arm" (xArm6 with gripper), "kuka" (KUKA iiwa), "conveyor" (the xArm6 at a belt, a bin
and an end-effector camera), "buggy" (Buggy's arena). Options are the world class's keyword
arguments (`time_step` included).
"""
from __future__ import annotations

from typing import Any, Callable

from .plant import Plant


def _arm(**options: Any) -> Plant:
    from .arm import ArmWorld
    return ArmWorld("xarm6", **options)


def _kuka(**options: Any) -> Plant:
    from .arm import ArmWorld
    return ArmWorld("kuka_iiwa", **options)


def _conveyor(**options: Any) -> Plant:
    from .conveyor import ConveyorWorld
    return ConveyorWorld(**options)


def _buggy(**options: Any) -> Plant:
    from .buggy import BuggyWorld
    return BuggyWorld(**options)


# imported on use: `iotad run --check` instantiates IOTAs without opening any world
WORLDS: dict[str, Callable[..., Plant]] = {"arm": _arm, "kuka": _kuka, "conveyor": _conveyor, "buggy": _buggy}

_open: dict[str, Plant] = {}


def make_world(name: str, **options: Any) -> Plant:
    """A new world of kind `name`; ValueError names the kinds there are or the bad option."""
    try:
        factory = WORLDS[name]
    except KeyError:
        raise ValueError(f"unknown world {name!r}; known: {', '.join(WORLDS)}") from None
    try:
        return factory(**options)
    except TypeError as exc:  # an option the world does not take
        raise ValueError(f"world {name!r}: {exc}") from None


def open_world(key: str, name: str, **options: Any) -> Plant:
    """`make_world`, registered under `key` so that other IOTAs of this process can find it.
    A key already taken is taken over (the older world stays open for whoever holds it): tools
    such as `iotad check` build the same instance more than once in a process."""
    world = make_world(name, **options)
    _open[key] = world
    return world


def find_world(key: str) -> Plant | None:
    return _open.get(key)


def close_world(key: str, world: Plant | None = None) -> None:
    """Close the world under `key` (only if it is `world`, when given) and forget the key."""
    found = _open.get(key)
    if found is None or (world is not None and found is not world):
        if world is not None:
            world.close()
        return
    del _open[key]
    found.close()
