"""ROS 2 messages through `rosbags`: the Jazzy type store, building a message from field values,
CDR bytes (with their 4-byte encapsulation header) both ways, and each type's RIHS01 hash.

rosbags ships the standard message definitions and its serializer is independent of iotad, so
nothing here hand-writes CDR. A message is built from a dict of field paths (`header.frame_id`,
`position`, `transforms[0].transform.translation.x`) to values: every field not given keeps its
zero value, sequences grow to the highest index a path names.
"""
from __future__ import annotations

import re
from functools import lru_cache
from typing import Any

import numpy as np

# The types a `[[ros2]]` table may name (docs/ros2.md); any other message of the store works
# the same way, but these are the ones tested.
SUPPORTED = (
    "sensor_msgs/msg/JointState", "geometry_msgs/msg/Twist", "geometry_msgs/msg/PoseStamped",
    "tf2_msgs/msg/TFMessage",
    "std_msgs/msg/Bool", "std_msgs/msg/Byte", "std_msgs/msg/Char", "std_msgs/msg/String",
    "std_msgs/msg/Float32", "std_msgs/msg/Float64",
    "std_msgs/msg/Int8", "std_msgs/msg/Int16", "std_msgs/msg/Int32", "std_msgs/msg/Int64",
    "std_msgs/msg/UInt8", "std_msgs/msg/UInt16", "std_msgs/msg/UInt32", "std_msgs/msg/UInt64",
)
DISTRO = "jazzy"
_NUMPY = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32,
          "int64": np.int64, "uint64": np.uint64, "float32": np.float32, "float64": np.float64}
INTEGER_RANGES = {"int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 255), "char": (0, 255),
                  "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1),
                  "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1)}
FLOATS = ("float32", "float64")
_STEP = re.compile(r"^([A-Za-z_]\w*)((?:\[\d+\])*)$")


class MessageError(ValueError):
    """A type or field a message does not have, or a value its field cannot hold."""


@lru_cache(maxsize=1)
def typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def check_type(ros_type: str) -> str:
    if ros_type not in typestore().fielddefs:
        supported = ", ".join(SUPPORTED)
        raise MessageError(f"unknown ROS 2 message type {ros_type!r} (supported: {supported})")
    return ros_type


def type_hash(ros_type: str) -> str:
    """The REP-2016 hash `RIHS01_<hex>` of a type, as rosidl computes it."""
    return typestore().hash_rihs01(check_type(ros_type))


def message_definition(ros_type: str) -> str:
    """The type's `.msg` text with its dependencies (rosbag2's `ros2msg` schema encoding)."""
    return typestore().generate_msgdef(check_type(ros_type), ros_version=2)[0]


@lru_cache(maxsize=1024)
def split_path(path: str) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """`transforms[0].transform.x` -> [("transforms", [0]), ("transform", []), ("x", [])]."""
    steps = []
    for part in path.split("."):
        match = _STEP.match(part)
        if not match:
            raise MessageError(f"{path!r} is not a field path such as header.frame_id or transforms[0].child_frame_id")
        steps.append((match.group(1), tuple(int(i) for i in re.findall(r"\d+", match.group(2)))))
    return tuple(steps)


def field_kind(ros_type: str, path: str) -> tuple[str, str]:
    """What the field at `path` of `ros_type` holds: ("base", "float64"), ("string", "string"),
    ("sequence", ELEMENT), ("array", ELEMENT) or ("message", TYPE). MessageError if there is none."""
    fielddefs = typestore().fielddefs
    current: tuple = (2, check_type(ros_type))  # Nodetype.NAME
    for name, indices in split_path(path):
        if current[0] != 2:
            raise MessageError(f"{ros_type}: {path!r}: {name!r} is inside a field that is not a message")
        fields = dict(fielddefs[current[1]][1])
        if name not in fields:
            raise MessageError(f"{ros_type}: {path!r}: {current[1]} has no field {name!r} "
                               f"(it has {', '.join(fields)})")
        nodetype, detail = fields[name]
        current = (int(nodetype), detail)
        for _ in indices:
            if current[0] not in (3, 4):  # ARRAY, SEQUENCE
                raise MessageError(f"{ros_type}: {path!r}: {name} is not a sequence or array")
            element, _size = current[1]
            current = (int(element[0]), element[1])
    nodetype, detail = current
    if nodetype == 1:
        return ("string", "string") if detail[0] in ("string", "wstring") else ("base", detail[0])
    if nodetype == 2:
        return "message", detail
    element = detail[0]
    shown = element[1][0] if int(element[0]) == 1 else element[1]
    return ("array" if nodetype == 3 else "sequence"), shown


def build(ros_type: str, values: dict[str, Any], stamp_ns: int | None = None) -> Any:
    """The message of `ros_type` with the field at each path of `values` set (others zero);
    with `stamp_ns`, every header whose stamp is still zero is stamped with it."""
    tree = _zero(ros_type)
    for path, value in values.items():
        _set(tree, split_path(path), value, ros_type, path)
    if stamp_ns is not None:
        _stamp(tree, {"sec": stamp_ns // 1_000_000_000, "nanosec": stamp_ns % 1_000_000_000})
    return _freeze(ros_type, tree)


def _stamp(node: Any, stamp: dict) -> None:
    if isinstance(node, list):
        if node and isinstance(node[0], (dict, list)):  # a sequence of numbers holds no header
            for item in node:
                _stamp(item, stamp)
    elif isinstance(node, dict):
        if node.keys() == {"stamp", "frame_id"} and node["stamp"] == {"sec": 0, "nanosec": 0}:
            node["stamp"] = dict(stamp)
            return
        for item in node.values():
            _stamp(item, stamp)


def to_dict(message: Any) -> dict[str, Any]:
    """A message as nested plain data: dicts, lists, numbers, strings."""
    return _plain(message)


def serialize(message: Any, ros_type: str) -> bytes:
    """CDR bytes, little-endian, with the 4-byte encapsulation header (00 01 00 00)."""
    return bytes(typestore().serialize_cdr(message, ros_type))


def deserialize(data: bytes, ros_type: str) -> Any:
    try:
        return typestore().deserialize_cdr(bytes(data), ros_type)
    except Exception as exc:  # noqa: BLE001 - rosbags raises several kinds on short or bad bytes
        raise MessageError(f"not CDR of {ros_type}: {type(exc).__name__}: {exc}") from None


# ---------------------------------------------------------------------------- building blocks

def _zero(ros_type: str) -> dict[str, Any]:
    tree = {}
    for name, (nodetype, detail) in typestore().fielddefs[ros_type][1]:
        tree[name] = _zero_of(int(nodetype), detail)
    return tree


def _zero_of(nodetype: int, detail: Any) -> Any:
    if nodetype == 1:
        return "" if detail[0] in ("string", "wstring") else (False if detail[0] == "bool" else 0)
    if nodetype == 2:
        return _zero(detail)
    element, size = detail
    if nodetype == 3:
        return [_zero_of(int(element[0]), element[1]) for _ in range(size)]
    return []


def _element_zero(ros_type: str, name: str) -> Any:
    nodetype, detail = dict(typestore().fielddefs[ros_type][1])[name]
    element = detail[0]
    return _zero_of(int(element[0]), element[1])


def _set(tree: dict, steps: list, value: Any, ros_type: str, path: str) -> None:
    current_type = ros_type
    node: Any = tree
    for number, (name, indices) in enumerate(steps):
        if not isinstance(node, dict) or name not in node:
            raise MessageError(f"{ros_type}: no field {path!r}")
        fields = dict(typestore().fielddefs[current_type][1])
        nodetype, detail = fields[name]
        last = number == len(steps) - 1
        if not indices:
            if last:
                node[name] = value
                return
            node, current_type = node[name], detail
            continue
        holder = node[name]
        for depth, index in enumerate(indices):
            while len(holder) <= index:
                if int(nodetype) == 3:
                    raise MessageError(f"{ros_type}: {path!r}: index {index} past the array's {len(holder)}")
                holder.append(_element_zero(current_type, name))
            if depth == len(indices) - 1:
                if last:
                    holder[index] = value
                    return
                node = holder[index]
            else:
                holder = holder[index]
        element = detail[0]
        current_type = element[1]


def _freeze(ros_type: str, tree: dict) -> Any:
    store = typestore()
    cls = store.types[ros_type]
    kwargs = {}
    for name, (nodetype, detail) in store.fielddefs[ros_type][1]:
        kwargs[name] = _freeze_value(int(nodetype), detail, tree[name], f"{ros_type}.{name}")
    return cls(**kwargs)


def _freeze_value(nodetype: int, detail: Any, value: Any, where: str) -> Any:
    if nodetype == 1:
        return _base(detail[0], value, where)
    if nodetype == 2:
        if not isinstance(value, dict):
            raise MessageError(f"{where}: a {detail} message, not {value!r}")
        return _freeze(detail, value)
    element, size = detail
    if not isinstance(value, (list, tuple, np.ndarray)):
        raise MessageError(f"{where}: a sequence, not {value!r}")
    if nodetype == 3 and len(value) != size:
        raise MessageError(f"{where}: an array of {size}, got {len(value)} values")
    kind, inner = int(element[0]), element[1]
    if kind == 1 and inner[0] in _NUMPY:
        return _numbers(inner[0], value, where)
    return [_freeze_value(kind, inner, v, where) for v in value]


def _numbers(name: str, values: Any, where: str) -> np.ndarray:
    """A sequence of numbers (or bools) as the array rosbags serializes, each checked as `_base` would."""
    given = np.asarray(values)
    if given.size and (given.dtype.kind not in "biuf" or (name == "bool") != (given.dtype.kind == "b")):
        return np.array([_base(name, v, where) for v in values], dtype=_NUMPY[name])  # says which value is wrong
    if name in FLOATS or name == "bool":
        return given.astype(_NUMPY[name])
    low, high = INTEGER_RANGES[name]
    if given.size and (given.dtype.kind == "f" and not np.all(given == np.floor(given))
                       or given.min() < low or given.max() > high):
        return np.array([_base(name, v, where) for v in values], dtype=_NUMPY[name])
    return given.astype(_NUMPY[name])


def _base(name: str, value: Any, where: str) -> Any:
    if name in ("string", "wstring"):
        if not isinstance(value, str):
            raise MessageError(f"{where}: a string, not {value!r}")
        return value
    if name == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise MessageError(f"{where}: a bool, not {value!r}")
        return bool(value)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise MessageError(f"{where}: a number ({name}), not {value!r}")
    if name in FLOATS:
        return float(value)
    if float(value) != int(value):
        raise MessageError(f"{where}: {name} takes integers, not {value!r}")
    low, high = INTEGER_RANGES[name]
    if not low <= int(value) <= high:
        raise MessageError(f"{where}: {value!r} does not fit in {name} [{low}, {high}]")
    return int(value)


def _plain(value: Any) -> Any:
    if hasattr(value, "__dataclass_fields__"):
        return {name: _plain(getattr(value, name)) for name in value.__dataclass_fields__
                if not name.startswith("__")}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
