"""Firing policies: when, inside what its window and switching time allow, an action fires.

    eager          the earliest time (the default)
    latest         the latest time; an unbounded window capped as `random` caps it
    random:SEED    a time drawn uniformly (seed 0 when `random` alone)

`parse_policy("latest")` makes one from its name; `PerNode` gives some nodes a policy of their
own while the rest keep the default (the engine asks it once per action instance, by the
instance's leaf path: `for_leaf`). Windows are contracts (docs/semantics.md): any of these
choices is a correct execution, which is what `iotad stress` runs a system under.
"""
from __future__ import annotations

import math
import random
from typing import Any, Mapping

HORIZON = 1.0  # spec time units an unbounded window is capped at, after its earliest time


def on_grid(t: float, not_before: float) -> float:
    """`t` on the engine's time grid (1e-9 of a time unit, as `engine.plus` puts window ends), never
    before `not_before`: a capped window's end 1 after a timeout's start is the same instant as
    that timeout, so the two fire in the order of their declaration, as any two due at once."""
    grid = round(t * 1e9) / 1e9
    return grid if grid >= not_before else not_before


class Eager:
    """Fire at the earliest allowed time (the window's lower bound, or the switching time)."""

    name = "eager"

    def choose(self, earliest: float, latest: float) -> float:
        return earliest

    def __str__(self) -> str:
        return "eager"


class Latest:
    """Fire at the latest allowed time: the window's upper bound, or the end of the switching
    time when that is later (the engine reports such a window as unreachable and fires there).
    An unbounded window is capped at `horizon` after its earliest time, as `Random` caps it."""

    name = "latest"

    def __init__(self, horizon: float = HORIZON):
        self.horizon = horizon

    def choose(self, earliest: float, latest: float) -> float:
        if latest < earliest or math.isinf(earliest):
            return earliest
        if math.isinf(latest):
            return on_grid(earliest + self.horizon, earliest)
        return latest

    def __str__(self) -> str:
        return "latest"


class Random:
    """Fire at a time drawn uniformly from what the window allows: explores the behaviours a
    spec permits. An unbounded window is capped at `horizon` after its earliest time."""

    name = "random"

    def __init__(self, seed: int = 0, horizon: float = HORIZON):
        self.seed, self.horizon = seed, horizon
        self._random = random.Random(seed)

    def choose(self, earliest: float, latest: float) -> float:
        if latest < earliest or math.isinf(earliest):
            return earliest  # never a NaN time: inf - inf would put one on the engine's heap
        if math.isinf(latest):
            latest = earliest + self.horizon
        return self._random.uniform(earliest, latest)

    def __str__(self) -> str:
        return f"random:{self.seed}"


class PerNode:
    """The default policy for every node but those named in `nodes` (node name -> policy), which
    fire by their own: stress one node while the world stays eager. A node is a path under the
    system's root (`buggy/avoid`); its components' leaves (`buggy/sim/world`) follow it."""

    name = "per-node"

    def __init__(self, default: Any, nodes: Mapping[str, Any], root: str = ""):
        self.default, self.nodes, self.root = default, dict(nodes), root

    def for_leaf(self, path: str) -> Any:
        """The policy of the action instances of the leaf at `path`."""
        inside = path[len(self.root) + 1:] if self.root and path.startswith(self.root + "/") else path
        node = inside.split("/")[0]
        return self.nodes.get(node, self.default)

    def choose(self, earliest: float, latest: float) -> float:  # (an engine asks `for_leaf` first)
        return self.default.choose(earliest, latest)

    def info(self) -> dict[str, Any]:
        return {"policy": self.name, "default": str(self.default),
                "nodes": {node: str(policy) for node, policy in sorted(self.nodes.items())}}

    def __str__(self) -> str:
        return f"{self.default}; " + ", ".join(f"{node}: {policy}" for node, policy in sorted(self.nodes.items()))


class PolicyError(ValueError):
    """A policy's name that is none of eager, latest, random[:SEED]."""


def parse_policy(text: str) -> Eager | Latest | Random:
    """`eager`, `latest`, `random` or `random:SEED` (a whole number from 0 to 2**64 - 1)."""
    name, colon, seed = str(text).strip().partition(":")
    if name == "random":
        if not colon:
            return Random(0)
        try:
            value = int(seed)
        except ValueError:
            value = -1
        if not 0 <= value < 2**64:
            raise PolicyError(f"policy {text!r}: the seed of random:SEED must be a whole number from 0 to 2**64 - 1")
        return Random(value)
    if not colon and name in ("eager", "latest"):
        return make_policy(name)
    raise PolicyError(f"unknown policy {text!r} (eager, latest, random or random:SEED)")


def make_policy(name: str, seed: int = 0) -> Eager | Latest | Random:
    if name == "eager":
        return Eager()
    if name == "latest":
        return Latest()
    if name == "random":
        return Random(seed)
    raise ValueError(f"unknown policy {name!r} (eager, latest or random)")
