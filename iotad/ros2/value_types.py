"""Channel value types as plain data and back, so that a bridge's channels can be built in the
node host from its parameters (JSON) with exactly the types of the channels it is bound to."""
from __future__ import annotations

from typing import Any

from iotad.kernel.types import ArrayType, BoolType, EnumType, FloatType, IntType, StructType, Type


def describe(t: Type | None) -> Any:
    """Plain data for a value type (None: a channel that carries no value)."""
    if t is None:
        return None
    if isinstance(t, (IntType, FloatType)):
        return {"kind": t.name, "low": t.low, "high": t.high}
    if isinstance(t, BoolType):
        return {"kind": "bool"}
    if isinstance(t, EnumType):
        return {"kind": "enum", "name": t.name, "members": list(t.members)}
    if isinstance(t, ArrayType):
        return {"kind": "array", "element": describe(t.element), "length": t.length}
    if isinstance(t, StructType):
        return {"kind": "struct", "name": t.name, "fields": [[n, describe(f)] for n, f in t.fields.items()]}
    raise TypeError(f"no plain description of the value type {t!r}")


def build(plain: Any) -> Type | None:
    """The type `describe` described."""
    if plain is None:
        return None
    kind = plain["kind"]
    if kind == "int":
        return IntType(plain["low"], plain["high"])
    if kind == "float":
        return FloatType(plain["low"], plain["high"])
    if kind == "bool":
        return BoolType()
    if kind == "enum":
        return EnumType(plain["name"], *plain["members"])
    if kind == "array":
        return ArrayType(build(plain["element"]), plain["length"])
    if kind == "struct":
        return StructType(plain["name"], **{name: build(field) for name, field in plain["fields"]})
    raise ValueError(f"unknown value type kind {kind!r}")


def at_path(t: Type | None, path: str) -> Type:
    """The type of the part of a value that `path` names: `.` the whole value, `position` a
    struct field, `position[2]` one element, `pose.x` a field of a field. KeyError says why not."""
    if path == ".":
        if t is None:
            raise KeyError("the channel carries no value")
        return t
    current = t
    for part in path.split("."):
        name, _, rest = part.partition("[")
        if not isinstance(current, StructType) or name not in current.fields:
            have = ", ".join(current.fields) if isinstance(current, StructType) else f"a {current!r}, no fields"
            raise KeyError(f"no field {name!r} in {path!r} (the value has {have})")
        current = current.fields[name]
        for index in [int(i) for i in rest.replace("]", "[").split("[") if i]:
            if not isinstance(current, ArrayType) or not 0 <= index < current.length:
                raise KeyError(f"{path!r}: [{index}] is past the value's array or not an array")
            current = current.element
    return current


def get(plain: Any, path: str) -> Any:
    """The part of a plain value that `path` names (see `at_path`)."""
    if path == ".":
        return plain
    for part in path.split("."):
        name, _, rest = part.partition("[")
        plain = plain[name]
        for index in [int(i) for i in rest.replace("]", "[").split("[") if i]:
            plain = plain[index]
    return plain


def put(plain: Any, path: str, value: Any) -> Any:
    """`plain` with the part `path` names replaced by `value` (the whole value for `.`)."""
    if path == ".":
        return value
    parts = path.split(".")
    holder = plain
    for number, part in enumerate(parts):
        name, _, rest = part.partition("[")
        indices = [int(i) for i in rest.replace("]", "[").split("[") if i]
        last = number == len(parts) - 1
        if not indices:
            if last:
                holder[name] = value
            else:
                holder = holder[name]
            continue
        holder = holder[name]
        for depth, index in enumerate(indices):
            if last and depth == len(indices) - 1:
                holder[index] = value
            else:
                holder = holder[index]
    return plain
