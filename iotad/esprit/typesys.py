"""ESPRIT's view of value types: the kernel's types (iotad.kernel.types) plus what only the compiler
needs: arrays whose length is a parameter, the type of NULL, and `void` for externs."""
from __future__ import annotations

from iotad.kernel.types import ArrayType, BoolType, EnumType, FloatType, IntType, StructType, Type


class ArrayOf:
    """A state array `x[N]`: its length is known only when the IOTA is instantiated."""

    def __init__(self, element, length=None):
        self.element, self.length = element, length
        self.name = f"{describe(element)}[]"


class _Marker:
    def __init__(self, name: str):
        self.name = name

    def __repr__(self) -> str:
        return self.name


NULL_T = _Marker("NULL")
VOID = _Marker("void")


def describe(t) -> str:
    if isinstance(t, StructType):
        return f"struct {t.name}"
    if isinstance(t, EnumType):
        return f"enum {t.name}"
    if isinstance(t, (ArrayType, ArrayOf)):
        return f"{describe(t.element)}[{'' if t.length is None else t.length}]"
    return getattr(t, "name", str(t))


# Values a state or a struct may hold in all, its nested arrays and fields counted: more is a slip
# (a parameter off by powers of ten) that would fill the memory before any error.
MAX_ELEMENTS = 1_000_000


def element_count(t) -> int:
    """How many scalar values a value of type `t` holds (an array of unknown length counts 1)."""
    if isinstance(t, ArrayType):
        return t.length * element_count(t.element)
    if isinstance(t, ArrayOf):
        return (t.length if isinstance(t.length, int) else 1) * element_count(t.element)
    if isinstance(t, StructType):
        return sum(element_count(f) for f in t.fields.values())
    return 1


def is_number(t) -> bool:
    return isinstance(t, (IntType, FloatType))


def is_int(t) -> bool:
    return isinstance(t, IntType)


def is_bool(t) -> bool:
    return isinstance(t, BoolType)


def element_of(t):
    return t.element if isinstance(t, (ArrayType, ArrayOf)) else None


def same(a, b) -> bool:
    """The same type, ranges aside."""
    if isinstance(a, (IntType, FloatType, BoolType)):
        return type(a) is type(b)
    if isinstance(a, (ArrayType, ArrayOf)):
        return isinstance(b, (ArrayType, ArrayOf)) and same(a.element, b.element)
    return a is b


def assignable(target, value) -> bool:
    """May a value of type `value` be stored where `target` is expected? ints widen to float;
    NULL fits anything (an unset value)."""
    if value is NULL_T:
        return True
    if isinstance(target, FloatType) and isinstance(value, IntType):
        return True
    if isinstance(target, (ArrayType, ArrayOf)) and isinstance(value, (ArrayType, ArrayOf)):
        lengths = (getattr(target, "length", None), getattr(value, "length", None))
        if None not in lengths and lengths[0] != lengths[1]:
            return False
        return assignable(target.element, value.element) and same(target.element, value.element) or \
            (isinstance(target.element, FloatType) and isinstance(value.element, IntType))
    return same(target, value)


def comparable(a, b) -> bool:
    if a is NULL_T or b is NULL_T:
        return True
    if is_number(a) and is_number(b):
        return True
    return same(a, b)


def has_null_member(t) -> bool:
    return isinstance(t, EnumType) and "NULL" in t.members


__all__ = ["ArrayOf", "ArrayType", "BoolType", "EnumType", "FloatType", "IntType", "NULL_T", "StructType",
           "Type", "VOID", "assignable", "comparable", "describe", "element_of", "has_null_member",
           "is_bool", "is_int", "is_number", "same"]
