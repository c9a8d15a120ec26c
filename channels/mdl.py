"""MDL motion programs as channel values, and the MDL interpreter's sensor and report messages.

A program is a plan: a sequence of behaviours, each a sequence of atoms <u, k, T, xi> (Brockett's
triple with an interrupt, as in MDLe); docs/mdl.md gives the format and its meaning. Programs are
variable-length, so `MDL_PROGRAM` is a value type of its own (`MdlProgramType`): it checks a
program whole at the channel boundary (so a malformed one is a `bad_value` violation where it
arrives, never a fault further on), has a JSON Schema for recordings, and its values are
immutable (`Program`), so copying one is free. The paper's `mode {w, k}` is accepted wherever a
program is, as the one-atom program it abbreviates (`mode_program`).

What the channel can check without knowing the robot it checks here: shapes, kinds, finite
numbers, bounds on sizes, and the syntax of every ESPRIT expression (interrupts and feedback
terms), with the column of a syntax error. Joint names and sensor names are the interpreter's:
it checks them when the program starts.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from iotad.kernel.types import Array, BadValue, Bool, Enum, Float, Int, Record, Struct, Type

from .messages import MODE

KINDS = ("hold", "ramp", "minimum_jerk", "velocity", "sine")

# Bounds that keep one program a bounded message (and a bounded amount of interpreter work).
MAX_ID = 64              # characters of a program id
MAX_NAME = 64            # characters of a behaviour name or a joint key
MAX_EXPRESSION = 400     # characters of an interrupt or a feedback expression
MAX_BEHAVIOURS = 64
MAX_ATOMS = 256          # per behaviour
# atoms in all: every one may end at the same instant (an interrupt that already holds), one
# atom_end firing each, and an engine allows 10,000 firings per instant before it halts (zeno)
MAX_PROGRAM_ATOMS = 4096
MAX_GAINS = 32           # feedback terms per atom
MAX_JOINTS = 64          # entries of one joint map (target, velocity, amplitude)
SENSOR_WIDTH = 8         # floats in one sensor reading


# ---------------------------------------------------------------- program values
@dataclass(frozen=True, slots=True)
class Pose:
    """An end-effector pose in the robot's base frame: metres, and a quaternion (x, y, z, w) or
    None for "any orientation"."""

    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float] | None = None


@dataclass(frozen=True, slots=True)
class Motion:
    """u, the open-loop input of an atom. Joint maps are ((joint key, value), ...), a joint key
    being a joint name or a decimal index; joints a map leaves out hold."""

    kind: str
    target: tuple[tuple[str, float], ...] = ()      # ramp, minimum_jerk: joint-space target
    pose: Pose | None = None                        # ramp, minimum_jerk: or an end-effector pose
    velocity: tuple[tuple[str, float], ...] = ()    # velocity: rad/s (m/s) per joint
    amplitude: tuple[tuple[str, float], ...] = ()   # sine: per joint
    frequency: float = 0.0                          # sine: Hz
    phase: float = 0.0                              # sine: radians


@dataclass(frozen=True, slots=True)
class Gain:
    """One term of k: `gain * value(sensor)` is added to the joint's velocity. `sensor` is an
    ESPRIT expression of type float over the interpreter's inputs (`visual_error.x`)."""

    joint: str
    sensor: str
    gain: float


@dataclass(frozen=True, slots=True)
class Atom:
    u: Motion
    k: tuple[Gain, ...] = ()
    T: float | None = None   # seconds; None: until an interrupt or a new command ends it
    xi: str = ""             # interrupt: an ESPRIT bool expression; "" for none


@dataclass(frozen=True, slots=True)
class Behaviour:
    atoms: tuple[Atom, ...]
    name: str = ""
    xi: str = ""


@dataclass(frozen=True, slots=True)
class Program:
    """A plan: what one `mdl_command` carries. `id` names it: re-sending an equal program with
    the same id resumes it where it was preempted."""

    id: str
    behaviours: tuple[Behaviour, ...]
    xi: str = ""

    def atoms(self):
        """(behaviour index, atom index, atom) for every atom, in order."""
        for b, behaviour in enumerate(self.behaviours):
            for a, atom in enumerate(behaviour.atoms):
                yield b, a, atom


# ---------------------------------------------------------------- plain <-> values
def _fail(path: str, message: str) -> BadValue:
    return BadValue(f"{path}: {message}")


def _object(plain: Any, path: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> dict:
    if not isinstance(plain, dict):
        raise _fail(path, f"expected an object, got {type(plain).__name__}")
    unknown = sorted(str(k) for k in plain if k not in allowed)
    if unknown:
        raise _fail(path, f"unknown field(s) {unknown}; allowed: {list(allowed)}")
    missing = [k for k in required if k not in plain]
    if missing:
        raise _fail(path, f"missing field(s) {missing}")
    return plain


def _number(plain: Any, path: str, positive: bool = False) -> float:
    if isinstance(plain, bool) or not isinstance(plain, (int, float)):
        raise _fail(path, f"expected a number, got {type(plain).__name__} {plain!r}")
    value = float(plain)
    if not math.isfinite(value):
        raise _fail(path, f"expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise _fail(path, f"expected a number > 0, got {value!r}")
    return value


def _text(plain: Any, path: str, limit: int, empty: bool = True) -> str:
    if not isinstance(plain, str):
        raise _fail(path, f"expected a string, got {type(plain).__name__}")
    if len(plain) > limit:
        raise _fail(path, f"longer than {limit} characters")
    if not _unicode(plain):
        raise _fail(path, f"not Unicode text (a lone surrogate: {plain!r})")
    if not empty and not plain.strip():
        raise _fail(path, "must not be empty")
    return plain


def _unicode(text: str) -> bool:
    """Whether `text` is Unicode that UTF-8 (the wire's and the recordings' strings) can carry:
    JSON's escapes can make a lone surrogate ("\\ud800"), which no encoder takes."""
    if text.isascii():
        return True
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _list(plain: Any, path: str, limit: int, empty: bool = False) -> list:
    if not isinstance(plain, (list, tuple)):
        raise _fail(path, f"expected a list, got {type(plain).__name__}")
    if len(plain) > limit:
        raise _fail(path, f"more than {limit} entries ({len(plain)})")
    if not empty and not plain:
        raise _fail(path, "must not be empty")
    return list(plain)


@lru_cache(maxsize=1024)
def expression_error(text: str) -> str | None:
    """None if `text` is a syntactically valid ESPRIT expression, else the diagnostic (with the
    line, column and caret). Names and types are checked by the interpreter, which knows them."""
    from iotad.esprit.errors import EspritError
    from iotad.esprit.expressions import parse_expression

    try:
        parse_expression(text)
    except EspritError as exc:
        return str(exc)
    return None


def _expression(plain: Any, path: str, empty: bool) -> str:
    text = _text(plain, path, MAX_EXPRESSION)
    if not text.strip():
        if empty:
            return ""
        raise _fail(path, "expected an expression")
    error = expression_error(text)
    if error is not None:
        raise _fail(path, f"not an ESPRIT expression: {error}")
    return text


def _joint_map(plain: Any, path: str) -> tuple[tuple[str, float], ...]:
    if not isinstance(plain, dict):
        raise _fail(path, f"expected an object of joint -> number, got {type(plain).__name__}")
    if not plain:
        raise _fail(path, "names no joint")
    if len(plain) > MAX_JOINTS:
        raise _fail(path, f"more than {MAX_JOINTS} joints")
    out = []
    for key, value in plain.items():
        _text(key, f"{path} key", MAX_NAME, empty=False)
        out.append((key, _number(value, f"{path}.{key}")))
    return tuple(out)


def _vector(plain: Any, path: str, length: int) -> tuple[float, ...]:
    items = _list(plain, path, length)
    if len(items) != length:
        raise _fail(path, f"expected {length} numbers, got {len(items)}")
    return tuple(_number(v, f"{path}[{i}]") for i, v in enumerate(items))


def _pose(plain: Any, path: str) -> Pose:
    _object(plain, path, ("position", "orientation"), ("position",))
    position = _vector(plain["position"], f"{path}.position", 3)
    orientation = plain.get("orientation")
    if orientation is not None:
        orientation = _vector(orientation, f"{path}.orientation", 4)
        if math.sqrt(sum(v * v for v in orientation)) < 1e-9:
            raise _fail(f"{path}.orientation", "a quaternion of length 0")
    return Pose(position, orientation)


_MOTION_FIELDS = {"hold": (), "ramp": ("target", "pose"), "minimum_jerk": ("target", "pose"),
                  "velocity": ("velocity",), "sine": ("amplitude", "frequency", "phase")}


def _motion(plain: Any, path: str) -> Motion:
    if not isinstance(plain, dict) or "kind" not in plain:
        raise _fail(path, f"expected an object with a kind (one of {list(KINDS)})")
    kind = plain["kind"]
    if kind not in _MOTION_FIELDS:
        raise _fail(f"{path}.kind", f"{kind!r} is not one of {list(KINDS)}")
    _object(plain, path, ("kind",) + _MOTION_FIELDS[kind])
    if kind in ("ramp", "minimum_jerk"):
        if ("target" in plain) == ("pose" in plain):
            raise _fail(path, f"a {kind} goes to a joint target or to a pose: give exactly one")
        if "pose" in plain:
            return Motion(kind, pose=_pose(plain["pose"], f"{path}.pose"))
        return Motion(kind, target=_joint_map(plain["target"], f"{path}.target"))
    if kind == "velocity":
        _object(plain, path, ("kind", "velocity"), ("velocity",))
        return Motion(kind, velocity=_joint_map(plain["velocity"], f"{path}.velocity"))
    if kind == "sine":
        _object(plain, path, ("kind", "amplitude", "frequency", "phase"), ("amplitude", "frequency"))
        return Motion(kind, amplitude=_joint_map(plain["amplitude"], f"{path}.amplitude"),
                      frequency=_number(plain["frequency"], f"{path}.frequency", positive=True),
                      phase=_number(plain.get("phase", 0.0), f"{path}.phase"))
    return Motion(kind)


def _gain(plain: Any, path: str) -> Gain:
    _object(plain, path, ("joint", "sensor", "gain"), ("joint", "sensor", "gain"))
    return Gain(_text(plain["joint"], f"{path}.joint", MAX_NAME, empty=False),
                _expression(plain["sensor"], f"{path}.sensor", empty=False),
                _number(plain["gain"], f"{path}.gain"))


def _atom(plain: Any, path: str) -> Atom:
    _object(plain, path, ("u", "k", "T", "xi"), ("u",))
    u = _motion(plain["u"], f"{path}.u")
    k = tuple(_gain(g, f"{path}.k[{i}]") for i, g in enumerate(_list(plain.get("k", []), f"{path}.k", MAX_GAINS, empty=True)))
    T = plain.get("T")
    T = None if T is None else _number(T, f"{path}.T", positive=True)
    if T is None and u.kind in ("ramp", "minimum_jerk"):
        raise _fail(f"{path}.T", f"a {u.kind} needs a duration T")
    return Atom(u, k, T, _expression(plain.get("xi", ""), f"{path}.xi", empty=True))


def _behaviour(plain: Any, path: str) -> Behaviour:
    _object(plain, path, ("name", "xi", "atoms"), ("atoms",))
    atoms = tuple(_atom(a, f"{path}.atoms[{i}]") for i, a in enumerate(_list(plain["atoms"], f"{path}.atoms", MAX_ATOMS)))
    return Behaviour(atoms, _text(plain.get("name", ""), f"{path}.name", MAX_NAME),
                     _expression(plain.get("xi", ""), f"{path}.xi", empty=True))


def program_from_plain(plain: Any, path: str = "mdlProgram") -> Program:
    """A checked `Program` from plain data (a program object, or a mode {w, k}); BadValue if it
    is not one, naming the offending field: `mdlProgram.behaviours[0].atoms[2].T: ...`."""
    if isinstance(plain, dict) and set(plain) == {"w", "k"}:
        return mode_program(_number(plain["w"], f"{path}.w"), _number(plain["k"], f"{path}.k"))
    _object(plain, path, ("id", "xi", "behaviours"), ("id", "behaviours"))
    behaviours = tuple(_behaviour(b, f"{path}.behaviours[{i}]")
                       for i, b in enumerate(_list(plain["behaviours"], f"{path}.behaviours", MAX_BEHAVIOURS)))
    total = sum(len(b.atoms) for b in behaviours)
    if total > MAX_PROGRAM_ATOMS:
        raise _fail(f"{path}.behaviours", f"{total} atoms in all; a program has at most {MAX_PROGRAM_ATOMS}")
    return Program(_text(plain["id"], f"{path}.id", MAX_ID, empty=False), behaviours,
                   _expression(plain.get("xi", ""), f"{path}.xi", empty=True))


def _map_plain(pairs: tuple[tuple[str, float], ...]) -> dict:
    return {key: value for key, value in pairs}


def motion_to_plain(u: Motion) -> dict:
    out: dict[str, Any] = {"kind": u.kind}
    if u.kind in ("ramp", "minimum_jerk"):
        if u.pose is not None:
            out["pose"] = {"position": list(u.pose.position),
                           "orientation": None if u.pose.orientation is None else list(u.pose.orientation)}
        else:
            out["target"] = _map_plain(u.target)
    elif u.kind == "velocity":
        out["velocity"] = _map_plain(u.velocity)
    elif u.kind == "sine":
        out.update(amplitude=_map_plain(u.amplitude), frequency=u.frequency, phase=u.phase)
    return out


def program_to_plain(program: Program) -> dict:
    """The canonical plain form: every field present, in the order docs/mdl.md shows."""
    return {"id": program.id, "xi": program.xi, "behaviours": [
        {"name": b.name, "xi": b.xi, "atoms": [
            {"u": motion_to_plain(a.u), "k": [{"joint": g.joint, "sensor": g.sensor, "gain": g.gain} for g in a.k],
             "T": a.T, "xi": a.xi} for a in b.atoms]} for b in program.behaviours]}


# ---------------------------------------------------------------- the paper's mode
MODE_JOINT = "0"  # the joint a mode drives: the first one


def mode_program(w: float, k: float) -> Program:
    """The one-atom program that the paper's mode {w, k} abbreviates: hold every joint, and
    drive the first joint toward the setpoint w with feedback gain k on its measured position
    (velocity k * (w - position[0])), with no duration and no interrupt: it runs until the next
    command. The id says w and k, so that two modes are two programs."""
    w, k = float(w), float(k)
    return Program(f"mode w={w!r} k={k!r}", (Behaviour((
        Atom(Motion("hold"), (Gain(MODE_JOINT, f"{w!r} - position[{MODE_JOINT}]", k),)),), "mode"),))


# ---------------------------------------------------------------- the value types
class TextType(Type):
    """A string of at most `limit` characters (program ids and conditions in reports)."""

    def __init__(self, limit: int):
        self.limit = int(limit)
        self.name = f"text[{self.limit}]"

    def check(self, value: Any) -> None:
        if not isinstance(value, str):
            raise BadValue(f"expected a string, got {type(value).__name__} {value!r}")
        if len(value) > self.limit:
            raise BadValue(f"a string longer than {self.limit} characters")
        if not _unicode(value):
            raise BadValue(f"not Unicode text (a lone surrogate: {value!r})")

    def default(self) -> str:
        return ""

    def json_schema(self) -> dict:
        return {"type": "string", "maxLength": self.limit}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, TextType) and other.limit == self.limit

    def __hash__(self) -> int:
        return hash(("text", self.limit))


def Text(limit: int) -> TextType:
    return TextType(limit)


class MdlProgramType(Type):
    """The value type of an MDL program (`mdlProgram`). Values are `Program`s; plain data is the
    canonical object of docs/mdl.md (or a mode {w, k}, which becomes its one-atom program)."""

    name = "mdlProgram"

    def check(self, value: Any) -> None:
        if not isinstance(value, Program):
            raise BadValue(f"expected an MDL program, got {type(value).__name__}")
        # A Program built by hand (not through from_plain) is checked the same way.
        program_from_plain(program_to_plain(value))

    def copy(self, value: Any) -> Any:
        return value  # immutable

    def to_plain(self, value: Any) -> Any:
        return None if value is None else program_to_plain(value)

    def from_plain(self, plain: Any) -> Program:
        if isinstance(plain, Program):
            self.check(plain)
            return plain
        if isinstance(plain, Record) and plain._type is MODE:
            return mode_program(plain.w, plain.k)
        return program_from_plain(plain)

    def default(self) -> Program:
        return HOLD

    def prepare(self) -> None:
        # A program's expressions are parsed as its value is checked; the first parse imports
        # the ESPRIT front end and builds its grammar (~0.1 s): at start-up, not in a firing.
        from iotad.esprit.expressions import parse_expression
        parse_expression("0")

    def json_schema(self) -> dict:
        return {"title": self.name, "anyOf": [_program_schema(), MODE.json_schema()]}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MdlProgramType)

    def __hash__(self) -> int:
        return hash(self.name)


def _program_schema() -> dict:
    text = {"type": "string", "maxLength": MAX_EXPRESSION}
    joints = {"type": "object", "minProperties": 1, "maxProperties": MAX_JOINTS,
              "additionalProperties": {"type": "number"}}
    kind = lambda *names: {"enum": list(names)}  # noqa: E731
    motions = [
        {"type": "object", "properties": {"kind": kind("hold")}, "required": ["kind"], "additionalProperties": False},
        {"type": "object", "properties": {"kind": kind("ramp", "minimum_jerk"), "target": joints},
         "required": ["kind", "target"], "additionalProperties": False},
        {"type": "object", "properties": {"kind": kind("ramp", "minimum_jerk"), "pose": {
            "type": "object", "properties": {
                "position": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                "orientation": {"anyOf": [{"type": "null"}, {"type": "array", "items": {"type": "number"},
                                                              "minItems": 4, "maxItems": 4}]}},
            "required": ["position"], "additionalProperties": False}},
         "required": ["kind", "pose"], "additionalProperties": False},
        {"type": "object", "properties": {"kind": kind("velocity"), "velocity": joints},
         "required": ["kind", "velocity"], "additionalProperties": False},
        {"type": "object", "properties": {"kind": kind("sine"), "amplitude": joints,
                                          "frequency": {"type": "number", "exclusiveMinimum": 0},
                                          "phase": {"type": "number"}},
         "required": ["kind", "amplitude", "frequency"], "additionalProperties": False},
    ]
    gain = {"type": "object", "properties": {"joint": {"type": "string", "minLength": 1, "maxLength": MAX_NAME},
                                             "sensor": text, "gain": {"type": "number"}},
            "required": ["joint", "sensor", "gain"], "additionalProperties": False}
    atom = {"type": "object", "title": "atom", "properties": {
        "u": {"oneOf": motions}, "k": {"type": "array", "items": gain, "maxItems": MAX_GAINS},
        "T": {"anyOf": [{"type": "null"}, {"type": "number", "exclusiveMinimum": 0}]}, "xi": text},
        "required": ["u"], "additionalProperties": False}
    behaviour = {"type": "object", "title": "behaviour", "properties": {
        "name": {"type": "string", "maxLength": MAX_NAME}, "xi": text,
        "atoms": {"type": "array", "items": atom, "minItems": 1, "maxItems": MAX_ATOMS}},
        "required": ["atoms"], "additionalProperties": False}
    return {"type": "object", "title": "plan", "properties": {
        "id": {"type": "string", "minLength": 1, "maxLength": MAX_ID}, "xi": text,
        "behaviours": {"type": "array", "items": behaviour, "minItems": 1, "maxItems": MAX_BEHAVIOURS}},
        "required": ["id", "behaviours"], "additionalProperties": False}


MDL_PROGRAM = MdlProgramType()

# The program that holds every joint where it is, until the next command.
HOLD = Program("hold", (Behaviour((Atom(Motion("hold")),), "hold"),))

# A request carrying a program: Figure 2's mdlReq with the program in place of the mode.
MDL_PROGRAM_REQ = Struct("mdlProgramReq", control=MDL_PROGRAM, epoch=Float(0, None), timeout=Float(0, None),
                         priority=Int)

# One sensor input of the interpreter: up to SENSOR_WIDTH floats, named by the interpreter's
# `sensors` parameter (visual_error: x, y); `valid` false means "no measurement" (target lost).
SENSOR_READING = Struct("sensorReading", valid=Bool, value=Array(Float, SENSOR_WIDTH))

# How an atom or a program ended, and which interrupt (if any) ended it.
MDL_END = Enum("mdlEnd", "DONE", "INTERRUPTED", "PREEMPTED", "FAULT")
MDL_LEVEL = Enum("mdlLevel", "NONE", "ATOM", "BEHAVIOUR", "PLAN")

ATOM_END = Struct("mdlAtomEnd", program=Text(MAX_ID), behaviour=Int(0, None), atom=Int(0, None), end=MDL_END,
                  level=MDL_LEVEL, condition=Text(MAX_EXPRESSION), tick=Int(0, None), t=Float(0, None),
                  elapsed=Float(0, None))
PROGRAM_END = Struct("mdlProgramEnd", program=Text(MAX_ID), end=MDL_END, level=MDL_LEVEL,
                     condition=Text(MAX_EXPRESSION), behaviour=Int(0, None), atom=Int(0, None),
                     tick=Int(0, None), t=Float(0, None))
MDL_FAULT = Struct("mdlFault", program=Text(MAX_ID), message=Text(2000), tick=Int(0, None), t=Float(0, None))

TYPES = (MDL_PROGRAM, MDL_PROGRAM_REQ, SENSOR_READING, MDL_END, MDL_LEVEL, ATOM_END, PROGRAM_END, MDL_FAULT)


# ---------------------------------------------------------------- building programs in Python
def _joints(mapping: dict | None) -> dict:
    return {str(k): v for k, v in (mapping or {}).items()}


def hold(**atom: Any) -> dict:
    """Atom builders return plain data; `program(...)` checks the whole and returns a Program."""
    return dict(atom, u={"kind": "hold"})


def ramp(target: dict, T: float, **atom: Any) -> dict:
    return dict(atom, u={"kind": "ramp", "target": _joints(target)}, T=T)


def minimum_jerk(target: dict | None = None, T: float = 1.0, pose: dict | None = None, **atom: Any) -> dict:
    u = {"kind": "minimum_jerk", **({"pose": pose} if pose is not None else {"target": _joints(target)})}
    return dict(atom, u=u, T=T)


def velocity(velocities: dict, **atom: Any) -> dict:
    return dict(atom, u={"kind": "velocity", "velocity": _joints(velocities)})


def sine(amplitude: dict, frequency: float, phase: float = 0.0, **atom: Any) -> dict:
    return dict(atom, u={"kind": "sine", "amplitude": _joints(amplitude), "frequency": frequency, "phase": phase})


def gain(joint: Any, sensor: str, value: float) -> dict:
    return {"joint": str(joint), "sensor": sensor, "gain": value}


def behaviour(*atoms: dict, name: str = "", xi: str = "") -> dict:
    return {"name": name, "xi": xi, "atoms": list(atoms)}


def program(id: str, *parts: dict, xi: str = "") -> Program:
    """`program("pick", ramp({...}, 2.0), hold(T=1))`: atoms make one behaviour; or give
    behaviours (`behaviour(...)`). Raises BadValue as the channel would."""
    behaviours = list(parts) if parts and all("atoms" in p for p in parts) else [behaviour(*parts)]
    return program_from_plain({"id": id, "xi": xi, "behaviours": behaviours})


__all__ = ["ATOM_END", "Atom", "Behaviour", "Gain", "HOLD", "KINDS", "MDL_END", "MDL_FAULT", "MDL_LEVEL",
           "MDL_PROGRAM", "MDL_PROGRAM_REQ", "MdlProgramType", "Motion", "PROGRAM_END", "Pose", "Program",
           "SENSOR_READING", "SENSOR_WIDTH", "TYPES", "Text", "TextType", "behaviour", "expression_error", "gain",
           "hold", "minimum_jerk", "mode_program", "motion_to_plain", "program", "program_from_plain",
           "program_to_plain", "ramp", "sine", "velocity"]
