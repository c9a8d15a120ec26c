"""Comparing recorded values (plain: numbers, strings, lists, maps, as msgpack carries them).

`values_equal` is exact, for the same message seen twice (delivery: sender, wire, receiver): a
NaN equals a NaN at any depth (Python's `==` says `[nan] != [nan]` for two decoded copies), and
1 equals 1.0 as msgpack may carry either. `values_close` is tolerant, for a value computed
twice (conformance and replay: a recorded value against the spec's): floats within 1e-9
relative (1e-12 absolute).
"""
from __future__ import annotations

import math
from typing import Any


def values_equal(a: Any, b: Any) -> bool:
    """Whether `a` and `b` are the same value, NaN equal to NaN wherever it is."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(values_equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and type(a) is type(b):
        return len(a) == len(b) and all(values_equal(x, y) for x, y in zip(a, b))
    return a == b


def values_close(a: Any, b: Any) -> bool:
    """Whether `a` and `b` agree, floats within a relative 1e-9 (absolute 1e-12) at any depth."""
    if isinstance(a, float) or isinstance(b, float):
        try:
            return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
        except TypeError:
            return False
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(values_close(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(values_close(x, y) for x, y in zip(a, b))
    return a == b
