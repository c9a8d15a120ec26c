"""Firing policies: when, inside what its window and switching time allow, an action fires."""
from __future__ import annotations

import math
import random


class Eager:
    """Fire at the earliest allowed time (the window's lower bound, or the switching time)."""

    name = "eager"

    def choose(self, earliest: float, latest: float) -> float:
        return earliest


class Random:
    """Fire at a time drawn uniformly from what the window allows: explores the behaviours a
    spec permits. An unbounded window is capped at `horizon` after its earliest time."""

    name = "random"

    def __init__(self, seed: int = 0, horizon: float = 1.0):
        self.seed, self.horizon = seed, horizon
        self._random = random.Random(seed)

    def choose(self, earliest: float, latest: float) -> float:
        if latest < earliest or math.isinf(earliest):
            return earliest  # never a NaN time: inf - inf would put one on the engine's heap
        if math.isinf(latest):
            latest = earliest + self.horizon
        return self._random.uniform(earliest, latest)


def make_policy(name: str, seed: int = 0) -> Eager | Random:
    if name == "eager":
        return Eager()
    if name == "random":
        return Random(seed)
    raise ValueError(f"unknown policy {name!r} (eager or random)")
