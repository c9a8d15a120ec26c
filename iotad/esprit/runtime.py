"""Helpers that compiled ESPRIT code calls at run time. Each raises an ordinary exception on a
fault (index out of range, NULL index, division by zero), which the engine turns into a
`runtime_error` violation while the IOTA goes on."""
from __future__ import annotations

from typing import Any

from iotad.types import Record


def ix(sequence: Any, index: Any) -> Any:
    """`a[k]` with C bounds: no negative indices from the end, no NULL index."""
    return sequence[_checked(sequence, index)]


def ix_set(sequence: Any, index: Any, value: Any) -> None:
    sequence[_checked(sequence, index)] = value


def _checked(sequence: Any, index: Any) -> int:
    if index is None:
        raise IndexError("index is NULL")
    if sequence is None:
        raise TypeError("indexing NULL")
    if not 0 <= index < len(sequence):
        raise IndexError(f"index {index} out of range [0, {len(sequence) - 1}]")
    return index


def c_div(left: int, right: int) -> int:
    """Integer division as in C: truncates toward zero."""
    if right == 0:
        raise ZeroDivisionError("integer division by zero")
    quotient = abs(left) // abs(right)
    return quotient if (left < 0) == (right < 0) else -quotient


def c_mod(left: int, right: int) -> int:
    if right == 0:
        raise ZeroDivisionError("integer modulo by zero")
    return left - right * c_div(left, right)


def cp(value: Any) -> Any:
    """A copy of a struct or array value, so that two cells never share one mutable value."""
    if isinstance(value, Record):
        return value._type.copy(value)
    if isinstance(value, list):
        return [cp(item) for item in value]
    return value


def field_of(value: Any, name: str) -> Any:  # pragma: no cover - kept for readable messages
    if value is None:
        raise AttributeError(f"field {name} of NULL")
    return getattr(value, name)
