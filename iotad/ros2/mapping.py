"""One `[[ros2]]` mapping: a channel to a ROS 2 topic, checked against both types, and the
conversion of a channel value to a message (direction out) or of a message to a value (in).

`fields` maps each field of the destination to where its value comes from: a field path of the
source (`"position"`, `"linear.x"`, `"."` for the whole value) or a constant (`{ value = ... }`).
Out, the destination is the message: a field not mapped keeps its zero value, except a
`header.stamp` (at any depth) left at zero, which gets the time the value was sent. In, the
destination is the channel's value: a field not mapped keeps the type's default.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from iotad.kernel.types import ArrayType, BoolType, EnumType, FloatType, IntType, Type
from iotad.ros2 import messages, rmw_zenoh, value_types
from iotad.ros2.messages import MessageError

DIRECTIONS = ("out", "in")
KEYS = {"channel", "topic", "type", "direction", "domain", "fields", "frame_id", "durability"}
DURABILITIES = ("volatile", "transient_local")
_SCALARS = {  # std_msgs scalar types: their one field `data`, mapped from the whole value by default
    t: "data" for t in messages.SUPPORTED if t.startswith("std_msgs/msg/")}


class MappingError(ValueError):
    """A `[[ros2]]` entry that cannot work; the message says which part and why."""


@dataclass
class Mapping:
    channel: str | None            # "node.channel" (an output for out, an input for in); None: constant
    topic: str                     # fully qualified: "/joint_states"
    ros_type: str                  # "sensor_msgs/msg/JointState"
    direction: str                 # out: iotad -> ROS 2; in: ROS 2 -> iotad
    domain: int = 0
    fields: dict[str, Any] = field(default_factory=dict)
    value_type: Any = None         # the channel's plain type description (value_types.describe)
    durability: str = "volatile"   # or "transient_local": late subscribers get the latest message

    def plain(self) -> dict[str, Any]:
        return {"channel": self.channel, "topic": self.topic, "type": self.ros_type, "direction": self.direction,
                "domain": self.domain, "fields": self.fields, "value_type": self.value_type,
                "durability": self.durability}

    @classmethod
    def from_plain(cls, plain: dict[str, Any]) -> "Mapping":
        # a recording made before durability existed holds volatile mappings
        return cls(plain["channel"], plain["topic"], plain["type"], plain["direction"], plain["domain"],
                   dict(plain["fields"]), plain.get("value_type"), plain.get("durability", "volatile"))

    @property
    def constant(self) -> bool:
        """A message of constants alone (`robot_description`): no channel, sent once and latched."""
        return self.channel is None

    @property
    def qos(self) -> str:
        """The QoS part of its liveliness token."""
        return rmw_zenoh.qos_token(self.durability == "transient_local")

    @property
    def type_hash(self) -> str:
        return messages.type_hash(self.ros_type)

    @property
    def key(self) -> str:
        return rmw_zenoh.data_key(self.domain, self.topic, self.ros_type, self.type_hash)

    # ------------------------------------------------------------------ conversions
    def to_message(self, plain: Any, stamp_ns: int) -> Any:
        """The message for one channel value (direction out); MessageError if a value does not fit."""
        values = {}
        for target, source in self.fields.items():
            values[target] = source["value"] if isinstance(source, dict) else value_types.get(plain, source)
        return messages.build(self.ros_type, values, stamp_ns=stamp_ns)

    def to_cdr(self, plain: Any, stamp_ns: int) -> bytes:
        return messages.serialize(self.to_message(plain, stamp_ns), self.ros_type)

    def reversed(self) -> "Mapping":
        """An in mapping turned around: the message a value of its input came from (the fields
        taken from the message; constants of the input are not in it). For recordings."""
        fields = {source: target for target, source in self.fields.items() if isinstance(source, str)}
        return Mapping(self.channel, self.topic, self.ros_type, "out", self.domain, fields, self.value_type)

    def from_cdr(self, data: bytes) -> Any:
        """The channel's plain value for one CDR message (direction in); MessageError if it is not one."""
        message = messages.to_dict(messages.deserialize(data, self.ros_type))
        plain = _default_plain(value_types.build(self.value_type))
        for target, source in self.fields.items():
            value = source["value"] if isinstance(source, dict) else _message_get(message, source)
            plain = value_types.put(plain, target, value)
        return plain


def parse(raw: Any, channel_type: Type | None, entry: str) -> Mapping:
    """A checked mapping from one `[[ros2]]` table; `channel_type` is the channel's value type."""
    if not isinstance(raw, dict):
        raise MappingError(f"{entry}: must be a table")
    unknown = sorted(set(raw) - KEYS)
    if unknown:
        raise MappingError(f"{entry}: unknown key(s) {', '.join(unknown)} (expected {', '.join(sorted(KEYS))})")
    for key in ("channel", "topic", "type", "direction"):
        if not isinstance(raw.get(key), str):
            raise MappingError(f"{entry}: needs {key} = \"...\" (a string)")
    direction = raw["direction"]
    if direction not in DIRECTIONS:
        raise MappingError(f"{entry}: direction must be \"out\" (iotad to ROS 2) or \"in\" (ROS 2 to an input), "
                           f"not {direction!r}")
    domain = raw.get("domain", 0)
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
        raise MappingError(f"{entry}: domain must be a ROS_DOMAIN_ID from 0 to 232, not {domain!r}")
    try:
        rmw_zenoh.check_topic(raw["topic"])
        messages.check_type(raw["type"])
    except ValueError as exc:
        raise MappingError(f"{entry}: {exc}") from None
    if channel_type is None:
        raise MappingError(f"{entry}: {raw['channel']} carries no value: nothing to put in a message")
    fields = raw.get("fields")
    if fields is None and raw["type"] in _SCALARS:
        fields = {"data": "."} if direction == "out" else {".": "data"}
    if not isinstance(fields, dict) or not fields:
        raise MappingError(f"{entry}: needs a fields table: each destination field = a source field path "
                           f"or {{ value = constant }}")
    fields = dict(fields)
    durability = parse_durability(raw, entry)
    if isinstance(raw.get("frame_id"), str):  # a shorthand: the message's header.frame_id
        fields.setdefault("header.frame_id", {"value": raw["frame_id"]})
    mapping = Mapping(raw["channel"], raw["topic"], raw["type"], direction, domain, fields,
                      value_types.describe(channel_type), durability)
    try:
        (_check_out if direction == "out" else _check_in)(mapping, channel_type)
    except (KeyError, MessageError, ValueError) as exc:
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        raise MappingError(f"{entry}: {text}") from None
    return mapping


def latched_by_default(topic: str) -> bool:
    """Topics ROS 2 tools expect to get late: `/robot_description` and `/tf_static` (also under a
    namespace), published transient local by robot_state_publisher and tf2's static broadcaster."""
    return topic.rsplit("/", 1)[-1] in ("robot_description", "tf_static")


def parse_durability(raw: dict, entry: str) -> str:
    durability = raw.get("durability", "transient_local" if latched_by_default(str(raw.get("topic"))) else "volatile")
    if durability not in DURABILITIES:
        raise MappingError(f"{entry}: durability must be \"volatile\" or \"transient_local\", not {durability!r}")
    return durability


def _check_out(mapping: Mapping, channel_type: Type) -> None:
    for target, source in mapping.fields.items():
        kind, element = messages.field_kind(mapping.ros_type, target)
        if isinstance(source, dict):
            if set(source) != {"value"}:
                raise ValueError(f"field {target!r}: a constant is written {{ value = ... }}")
            continue
        if not isinstance(source, str):
            raise ValueError(f"field {target!r}: the source is a field path of {mapping.channel} "
                             f"(\".\" for the whole value) or {{ value = ... }}, not {source!r}")
        _fits(value_types.at_path(channel_type, source), kind, element, f"{target} = {source!r}")
    # a whole message from the channel type's default value: constants and structure both fit
    mapping.to_message(_default_plain(channel_type), 0)


def _check_in(mapping: Mapping, channel_type: Type) -> None:
    for target, source in mapping.fields.items():
        part = value_types.at_path(channel_type, target)
        if isinstance(source, dict):
            if set(source) != {"value"}:
                raise ValueError(f"field {target!r}: a constant is written {{ value = ... }}")
            part.from_plain(source["value"])
            continue
        if not isinstance(source, str):
            raise ValueError(f"field {target!r}: the source is a field path of {mapping.ros_type} "
                             f"or {{ value = ... }}, not {source!r}")
        kind, element = messages.field_kind(mapping.ros_type, source)
        _fits(part, kind, element, f"{target} = {source!r}")


def _fits(part: Type, kind: str, element: str, where: str) -> None:
    """Whether a channel value of type `part` and a message field of (`kind`, `element`) can hold
    each other's values; ValueError naming both where not."""
    if isinstance(part, ArrayType):
        if kind not in ("sequence", "array"):
            raise ValueError(f"{where}: an array ({part!r}) against a field that holds one {element}")
        _fits(part.element, "string" if element in ("string", "wstring") else "base", element, where)
        return
    if kind in ("sequence", "array"):
        raise ValueError(f"{where}: one value ({part!r}) against a sequence of {element}")
    if kind == "message":
        raise ValueError(f"{where}: {element} is a message: map its fields one by one")
    ok = (isinstance(part, FloatType) and kind == "base" and element in messages.FLOATS
          or isinstance(part, IntType) and kind == "base" and element in messages.INTEGER_RANGES
          or isinstance(part, IntType) and kind == "base" and element in messages.FLOATS
          or isinstance(part, BoolType) and element == "bool"
          or isinstance(part, EnumType) and kind == "string")
    if not ok:
        raise ValueError(f"{where}: a {part!r} value and a {element} field do not fit each other")


def _default_plain(t: Type) -> Any:
    return t.to_plain(t.default())


def _message_get(message: dict, path: str) -> Any:
    current: Any = message
    for name, indices in messages.split_path(path):
        current = current[name]
        for index in indices:
            if index >= len(current):
                raise MessageError(f"{path}: the message's sequence has {len(current)} elements")
            current = current[index]
    return current


__all__ = ["Mapping", "MappingError", "parse"]
