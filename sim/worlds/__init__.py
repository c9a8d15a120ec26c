"""PyBullet worlds the simulated controllers drive, by name, and the worlds open in this process.

    world = make_world("arm")                 # a Plant: joints to read and drive (plant.py)
    world = open_world("sim", "conveyor", seed=3)   # the same, and findable by key ...
    find_world("sim")                         # ... by sensors composed in the same process

Names: "arm" (xArm6 with gripper), "kuka" (KUKA iiwa), "conveyor" (the xArm6 at a belt, a bin
and an end-effector camera), "buggy" (Buggy's arena), "urdf" (any robot from its URDF, option
`urdf`: its movable joints by the URDF's names). Options are the world class's keyword
arguments (`time_step` included).
"""
from __future__ import annotations

import importlib
import inspect
import math
from typing import Any

from .plant import Plant


# name -> (module, class, fixed arguments); a class is imported on use: `iotad run --check` opens no world
_CLASSES: dict[str, tuple[str, str, dict[str, Any]]] = {
    "arm": (".arm", "ArmWorld", {"robot": "xarm6"}), "kuka": (".arm", "ArmWorld", {"robot": "kuka_iiwa"}),
    "conveyor": (".conveyor", "ConveyorWorld", {}), "buggy": (".buggy", "BuggyWorld", {}),
    "urdf": (".urdf_world", "UrdfWorld", {})}
WORLDS = tuple(_CLASSES)


def _world_class(name: str) -> type:
    module, cls, _ = _CLASSES[name]
    return getattr(importlib.import_module(module, __package__), cls)


def world_options(name: str) -> dict[str, inspect.Parameter]:
    """The options world `name` takes: its class's keyword arguments (a subclass's `**rest`
    passes on to its base class's)."""
    cls = _world_class(name)
    options: dict[str, inspect.Parameter] = {}
    for klass in cls.__mro__:
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        more = False
        for parameter in list(inspect.signature(init).parameters.values())[1:]:
            if parameter.kind is parameter.VAR_KEYWORD:
                more = True
            elif parameter.name not in options:
                options[parameter.name] = parameter
        if not more:
            break
    for fixed in _CLASSES[name][2]:
        options.pop(fixed, None)
    return options


def check_options(name: str, options: dict[str, Any]) -> None:
    """ValueError naming the option for one the world does not take, or of the wrong kind (by
    its default: a number, a whole number, a flag, a list), or one it needs positive."""
    known = world_options(name)
    positive = getattr(_world_class(name), "POSITIVE_OPTIONS", ())
    for key, value in options.items():
        parameter = known.get(key)
        if parameter is None:
            raise ValueError(f"world {name!r} has no option {key!r}; its options: {', '.join(sorted(known))}")
        default = parameter.default
        if isinstance(default, bool):
            ok, kind = isinstance(value, bool), "true or false"
        elif isinstance(default, int):
            ok, kind = isinstance(value, int) and not isinstance(value, bool), "a whole number"
        elif isinstance(default, float):
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            kind = "a finite number"
        elif isinstance(default, (tuple, list)) or key in ("start", "cracks", "home"):
            ok, kind = value is None or isinstance(value, (tuple, list)), "a list"
        else:
            ok, kind = True, ""
        if not ok:
            raise ValueError(f"world {name!r}: option {key} must be {kind}, got {value!r}")
        if key in positive and not value > 0:
            raise ValueError(f"world {name!r}: option {key} must be > 0, got {value!r}")

_open: dict[str, Plant] = {}


def make_world(name: str, **options: Any) -> Plant:
    """A new world of kind `name`; ValueError names the kinds there are or the bad option."""
    if name not in _CLASSES:
        raise ValueError(f"unknown world {name!r}; known: {', '.join(WORLDS)}")
    check_options(name, options)
    try:
        return _world_class(name)(**_CLASSES[name][2], **options)
    except ValueError:
        raise
    except (ArithmeticError, TypeError, IndexError, KeyError) as exc:  # what the checks above did not foresee
        raise ValueError(f"world {name!r} cannot be built with options {options}: "
                         f"{type(exc).__name__}: {exc}") from None


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
