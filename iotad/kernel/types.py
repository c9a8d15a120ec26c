"""Value types carried by channels and held in state: int, float, bool, enums, structs, fixed arrays.

A type knows how to check a value (range included), copy it (so that two IOTAs never share a
mutable value), turn it into plain data for traces and msgpack (`to_plain`), build it back
(`from_plain`), and describe itself as JSON Schema. Enum values are their names (plain `str`),
so traces and payloads read the same as the specification.

Two shortcuts serve the engine's hot path (every output, every bound input), each the exact
equivalent of the slow pair it replaces, same values and same `BadValue` messages:

- `checked_plain(value)` is `check(value)` then `to_plain(value)` in one pass over the value;
- `from_checked_plain(plain)` is `from_plain(plain)` for plain data that `checked_plain` of this
  type (or of an equal one) returned: what `check` proved it does not prove again, but it still
  builds a fresh value (no list or record is shared with the sender or the trace) and still
  rejects what `from_plain` rejects that `check` lets through (a struct field left unset, None).

The fast paths accept values whose class is exactly the expected one (`int`, `float`, `list`,
the struct's record class); anything else, and anything wrong, goes through the slow path, which
gives the verdict and its message.
"""
from __future__ import annotations

import keyword
import math
import sys
from typing import Any


class BadValue(ValueError):
    """A value does not fit its declared type or range. Raised by `check` and `from_plain`."""


class Type:
    """Base of all value types. Subclasses override the few methods that differ."""

    name = "type"
    # True where `from_checked_plain` returns its argument itself (an int, a bool, an enum's
    # name): the engine then delivers the value without the call
    checked_plain_is_value = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # a subclass that redefines `from_checked_plain` does not inherit the promise
        if "from_checked_plain" in cls.__dict__ and "checked_plain_is_value" not in cls.__dict__:
            cls.checked_plain_is_value = False

    def check(self, value: Any) -> None:  # pragma: no cover - every type overrides it
        raise NotImplementedError

    def copy(self, value: Any) -> Any:
        return value

    def to_plain(self, value: Any) -> Any:
        return value

    def from_plain(self, plain: Any) -> Any:
        self.check(plain)
        return plain

    def checked_plain(self, value: Any) -> Any:
        """`check(value)`, then `to_plain(value)`; subclasses do both in one pass."""
        self.check(value)
        return self.to_plain(value)

    def from_checked_plain(self, plain: Any) -> Any:
        """`from_plain(plain)` where `plain` came from `checked_plain` of this type."""
        return self.from_plain(plain)

    def default(self) -> Any:  # pragma: no cover - every type overrides it
        raise NotImplementedError

    def json_schema(self) -> dict:  # pragma: no cover - every type overrides it
        raise NotImplementedError

    def prepare(self) -> None:
        """Work the type does once before its first value, done here instead: the engine calls
        it for every channel's type as it is built, so that the cost lands at start-up, not in
        the firing (or the real-time do-block) that carries the first value. Most types have none."""

    def __repr__(self) -> str:
        return self.name


class _Number(Type):
    py_types: tuple = ()
    schema_type = "number"

    def __init__(self, low: float | None = None, high: float | None = None):
        self.low, self.high = low, high
        self.checked_plain = self._fast_checker()

    def _fast_checker(self):
        """`checked_plain` as a closure: a value of exactly the expected class within the bounds
        is returned at once (a NaN fails every comparison, so it takes the slow path)."""
        lo, hi = _range(self)
        classes = tuple(c for c in self.py_types)  # bool is a subclass, never its exact class
        first, second = (classes + classes)[:2]
        check = self.check

        def checked_plain(value: Any) -> Any:
            cls = value.__class__
            if (cls is first or cls is second) and lo <= value <= hi:
                return value
            check(value)  # raises for what is wrong; a subclass of int or float that is fine passes
            return value
        return checked_plain

    def __call__(self, low: float | None = None, high: float | None = None) -> "_Number":
        """`Float(0, 1)` is a float restricted to [0, 1]."""
        return type(self)(low, high)

    def check(self, value: Any) -> None:
        if isinstance(value, bool) or not isinstance(value, self.py_types):
            raise BadValue(f"expected {self.name}, got {type(value).__name__} {value!r}")
        if self.low is not None and value < self.low or self.high is not None and value > self.high:
            low = "-inf" if self.low is None else self.low
            high = "inf" if self.high is None else self.high
            raise BadValue(f"{value!r} outside range [{low}, {high}]")

    def json_schema(self) -> dict:
        schema: dict = {"type": self.schema_type}
        if self.low is not None:
            schema["minimum"] = self.low
        if self.high is not None:
            schema["maximum"] = self.high
        return schema

    def __repr__(self) -> str:
        if self.low is None and self.high is None:
            return self.name
        return f"{self.name}[{self.low}..{self.high}]"

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and (self.low, self.high) == (other.low, other.high)

    def __hash__(self) -> int:
        return hash((self.name, self.low, self.high))


# The integers msgpack carries (the wire, the recordings): an int beyond them cannot be sent.
INT_MIN, INT_MAX = -(1 << 63), (1 << 64) - 1
_INT_RANGE = f"the wire and recordings carry integers from {INT_MIN} to {INT_MAX}"
# what to say of an integer of more digits than Python turns into text (4300): no text shows it
HUGE_INT = f"past 64 bits ({_INT_RANGE})"
_FLOAT_MAX = sys.float_info.max


def int_text(value: int) -> str:
    """`repr(value)`, or a description where Python would refuse (over 4300 digits)."""
    try:
        return repr(value)
    except ValueError:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"


def _range(number: "_Number") -> tuple:
    """The closed range a number type's fast paths accept at once: its bounds, and for an int
    also the 64 bits it is sent in; what lies outside takes the slow path (`check`)."""
    lo = -math.inf if number.low is None else number.low
    hi = math.inf if number.high is None else number.high
    if isinstance(number, IntType):
        lo, hi = max(lo, INT_MIN), min(hi, INT_MAX)
    return lo, hi


class IntType(_Number):
    name = "int"
    py_types = (int,)
    schema_type = "integer"

    def check(self, value: Any) -> None:
        super().check(value)
        if not INT_MIN <= value <= INT_MAX:
            raise BadValue(f"{int_text(value)} does not fit in 64 bits ({_INT_RANGE})")

    def default(self) -> int:
        return 0 if self.low is None else int(self.low)

    checked_plain_is_value = True

    def from_checked_plain(self, plain: Any) -> Any:
        return plain


class FloatType(_Number):
    name = "float"
    py_types = (int, float)

    def check(self, value: Any) -> None:
        super().check(value)
        if isinstance(value, float) and math.isnan(value):
            raise BadValue("NaN is not a valid float value")
        if isinstance(value, int) and not -_FLOAT_MAX <= value <= _FLOAT_MAX:
            raise BadValue(f"an int of {value.bit_length()} bits is too large for a float")

    def to_plain(self, value: Any) -> Any:
        # an int is sent as it is while msgpack carries it (64 bits), beyond as the float it stands for
        return float(value) if value.__class__ is not float and not INT_MIN <= value <= INT_MAX else value

    def from_plain(self, plain: Any) -> float:
        self.check(plain)
        return float(plain)

    def _fast_checker(self):
        """As for every number, but an int in a float channel is sent as it is only while
        msgpack carries it (64 bits); a larger one goes out as the float it stands for."""
        lo, hi = _range(self)
        int_lo, int_hi = max(lo, INT_MIN), min(hi, INT_MAX)
        check, to_plain = self.check, self.to_plain

        def checked_plain(value: Any) -> Any:
            cls = value.__class__
            if cls is float and lo <= value <= hi or cls is int and int_lo <= value <= int_hi:
                return value
            check(value)
            return to_plain(value)
        return checked_plain

    def from_checked_plain(self, plain: Any) -> float:
        return float(plain)

    def default(self) -> float:
        return 0.0 if self.low is None else float(self.low)


class BoolType(Type):
    name = "bool"

    def check(self, value: Any) -> None:
        if not isinstance(value, bool):
            raise BadValue(f"expected bool, got {type(value).__name__} {value!r}")

    def checked_plain(self, value: Any) -> Any:
        if value is True or value is False:
            return value
        self.check(value)
        return value

    checked_plain_is_value = True

    def from_checked_plain(self, plain: Any) -> Any:
        return plain

    def default(self) -> bool:
        return False

    def json_schema(self) -> dict:
        return {"type": "boolean"}


class EnumType(Type):
    """Symbolic values such as COMMIT, ABORT, REJECT. `Ack.COMMIT == "COMMIT"`."""

    def __init__(self, name: str, *members: str):
        if not members:
            raise BadValue(f"enum {name} needs at least one member")
        self.name, self.members = name, tuple(members)
        self._set = frozenset(members)
        for member in members:
            if not member.startswith("_") and member not in ("name", "members"):
                setattr(self, member, member)

    def check(self, value: Any) -> None:
        if not isinstance(value, str) or value not in self._set:  # a list is unhashable: ask str first
            raise BadValue(f"{value!r} is not a member of enum {self.name} {list(self.members)}")

    def checked_plain(self, value: Any) -> Any:
        if value.__class__ is str and value in self._set:
            return value
        self.check(value)
        return value

    checked_plain_is_value = True

    def from_checked_plain(self, plain: Any) -> Any:
        return plain

    def default(self) -> str:
        return self.members[0]

    def json_schema(self) -> dict:
        return {"type": "string", "enum": list(self.members), "title": self.name}


class Record:
    """A struct value: attribute access like the paper's `request[i].command.priority`."""

    __slots__ = ()
    _type: "StructType"

    def __init__(self, *args: Any, **fields: Any):
        names = self._type.field_names
        if len(args) > len(names):
            raise TypeError(f"{self._type.name} takes at most {len(names)} positional fields")
        for name, value in zip(names, args):
            fields[name] = value
        unknown = set(fields) - set(names)
        if unknown:
            raise TypeError(f"{self._type.name} has no field(s) {sorted(unknown)}")
        for name in names:
            object.__setattr__(self, name, fields[name] if name in fields else self._type.fields[name].default())

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Record) and other._type is self._type
                and all(getattr(self, n) == getattr(other, n) for n in self._type.field_names))

    __hash__ = None  # type: ignore[assignment]  # mutable

    def __repr__(self) -> str:
        inner = ", ".join(f"{n}={getattr(self, n)!r}" for n in self._type.field_names)
        return f"{self._type.name}({inner})"


class StructType(Type):
    """`Struct("mode", w=Float, k=Float)`; calling it builds a value: `Mode(w=1.0, k=0.5)`."""

    def __init__(self, name: str, **fields: Type):
        self.name = name
        self.fields: dict[str, Type] = {k: _as_type(v) for k, v in fields.items()}
        self.field_names = tuple(self.fields)
        self.record = type(name, (Record,), {"__slots__": self.field_names, "_type": self})
        self._checked_fields = tuple((n, t.checked_plain) for n, t in self.fields.items())
        self._built_fields = tuple((n, t.from_checked_plain) for n, t in self.fields.items())
        if all(n.isidentifier() and not keyword.iskeyword(n) for n in self.field_names):
            _compile_struct(self)

    def __call__(self, *args: Any, **fields: Any) -> Record:
        return self.record(*args, **fields)

    def prepare(self) -> None:
        for field_type in self.fields.values():
            field_type.prepare()

    def checked_plain(self, value: Any) -> Any:
        if value.__class__ is self.record:
            try:
                return {name: None if (v := getattr(value, name)) is None else checked(v)
                        for name, checked in self._checked_fields}
            except BadValue:
                pass  # the slow path below says which field, in its words
        self.check(value)
        return self.to_plain(value)

    def from_checked_plain(self, plain: Any) -> Any:
        new = object.__new__(self.record)
        try:
            for name, build in self._built_fields:
                v = plain[name]
                object.__setattr__(new, name, None if v is None else build(v))
        except BadValue:  # here or in a field: the slow path says what, from the top
            return self.from_plain(plain)
        return new

    def check(self, value: Any) -> None:
        if not isinstance(value, Record) or value._type is not self:
            raise BadValue(f"expected struct {self.name}, got {type(value).__name__}")
        for name, ftype in self.fields.items():
            field_value = getattr(value, name)
            if field_value is None:
                continue  # a struct field may be unset (NULL in the paper) until assigned
            try:
                ftype.check(field_value)
            except BadValue as exc:
                raise BadValue(f"{self.name}.{name}: {exc}") from None

    def copy(self, value: Any) -> Any:
        if value is None:
            return None
        new = object.__new__(self.record)
        for name, ftype in self.fields.items():
            object.__setattr__(new, name, ftype.copy(getattr(value, name)))
        return new

    def to_plain(self, value: Any) -> Any:
        if value is None:
            return None
        return {name: (None if (v := getattr(value, name)) is None else ftype.to_plain(v))
                for name, ftype in self.fields.items()}

    def from_plain(self, plain: Any) -> Record:
        if isinstance(plain, Record):
            self.check(plain)
            return self.copy(plain)
        if not isinstance(plain, dict):
            raise BadValue(f"expected an object for struct {self.name}, got {type(plain).__name__}")
        unknown = set(plain) - set(self.fields)
        if unknown:
            raise BadValue(f"struct {self.name} has no field(s) {sorted(unknown)}")
        missing = [n for n in self.field_names if n not in plain]
        if missing:
            raise BadValue(f"struct {self.name} is missing field(s) {missing}")
        new = object.__new__(self.record)
        for name, ftype in self.fields.items():
            try:
                # an unset field (NULL in the paper) passes check and goes out as None: it comes in so
                object.__setattr__(new, name, None if plain[name] is None else ftype.from_plain(plain[name]))
            except BadValue as exc:
                raise BadValue(f"{self.name}.{name}: {exc}") from None
        return new

    def default(self) -> Record:
        return self.record()

    def json_schema(self) -> dict:
        return {"type": "object", "title": self.name,
                "properties": {n: t.json_schema() for n, t in self.fields.items()},
                "required": list(self.field_names), "additionalProperties": False}


class ArrayType(Type):
    """A fixed-length array: `Array(Float, 6)` for six joint positions."""

    def __init__(self, element: Type, length: int):
        self.element, self.length = _as_type(element), int(length)
        self.name = f"{self.element.name}[{self.length}]"
        self._checked_element = self.element.checked_plain
        self._built_element = self.element.from_checked_plain
        # elements that are their own plain data and come back as they are (int, bool, enum)
        self._plain_elements = type(self.element).from_checked_plain in _IDENTITY_BUILDS
        if type(self.element) in (IntType, FloatType, BoolType) and self.length <= 16:
            _compile_array(self)

    def prepare(self) -> None:
        self.element.prepare()

    def checked_plain(self, value: Any) -> Any:
        if value.__class__ is list and len(value) == self.length:
            try:
                return list(map(self._checked_element, value))
            except BadValue:
                pass  # the slow path below says which element, in its words
        self.check(value)
        return self.to_plain(value)

    def from_checked_plain(self, plain: Any) -> list:
        if self._plain_elements:
            return list(plain)  # a fresh list: the receiver never shares the sender's
        try:
            return list(map(self._built_element, plain))
        except BadValue:  # an element's unset field: the slow path says which, from the top
            return self.from_plain(plain)

    def check(self, value: Any) -> None:
        if not isinstance(value, (list, tuple)) or len(value) != self.length:
            raise BadValue(f"expected {self.length} elements of {self.element.name}")
        for index, item in enumerate(value):
            try:
                self.element.check(item)
            except BadValue as exc:
                raise BadValue(f"[{index}]: {exc}") from None

    def copy(self, value: Any) -> list:
        return [self.element.copy(v) for v in value]

    def to_plain(self, value: Any) -> list:
        return [self.element.to_plain(v) for v in value]

    def from_plain(self, plain: Any) -> list:
        if not isinstance(plain, (list, tuple)) or len(plain) != self.length:
            raise BadValue(f"expected a list of {self.length} elements of {self.element.name}")
        out = []
        for index, item in enumerate(plain):
            try:
                out.append(self.element.from_plain(item))
            except BadValue as exc:
                raise BadValue(f"[{index}]: {exc}") from None
        return out

    def default(self) -> list:
        return [self.element.default() for _ in range(self.length)]

    def json_schema(self) -> dict:
        return {"type": "array", "items": self.element.json_schema(),
                "minItems": self.length, "maxItems": self.length}


Int = IntType()
Float = FloatType()
Bool = BoolType()


def Enum(name: str, *members: str) -> EnumType:
    return EnumType(name, *members)


def Struct(name: str, **fields: Type) -> StructType:
    return StructType(name, **fields)


def Array(element: Type, length: int) -> ArrayType:
    return ArrayType(element, length)


def _as_type(value: Any) -> Type:
    if isinstance(value, Type):
        return value
    builtin = {int: Int, float: Float, bool: Bool}
    if value in builtin:
        return builtin[value]
    raise TypeError(f"{value!r} is not a value type")


def to_plain(value: Any) -> Any:
    """Plain data for a value of unknown type (traces of untyped values)."""
    if isinstance(value, Record):
        return value._type.to_plain(value)
    if isinstance(value, (list, tuple)):
        return [to_plain(v) for v in value]
    return value


class CheckedPlain:
    """The mark of an input whose plain value a port already built with `type`'s checks (the CAN
    port's frames, checked as `iotad.can.frame.Frame` checks them): the engine then builds the value
    with `from_checked_plain` when the input's own type checks the same (`same_checks`), and
    records the plain value as it came, which is already as that type writes it. (The second check
    and its write-back were a tenth of a 500 Hz motor node's engine thread under cProfile;
    docs/performance.md, round 8, says what that bought.)"""

    __slots__ = ("type",)

    def __init__(self, type: Type) -> None:
        self.type = type


def same_checks(a: Type | None, b: Type | None) -> bool:
    """Whether every value `a.check` accepts `b.check` accepts too, and `b` builds it back from
    `a`'s plain data as `b.from_plain` would: the same type, an equal one, or one spelled the same
    (two loads of one ESPRIT file make two struct types with the same fields). The engine then
    delivers an output of type `a` to an input of type `b` with `b.from_checked_plain`."""
    if a is None or b is None:
        return False
    if a is b or a == b:
        return True
    kind = type(a)
    if kind is not type(b):
        return False
    if kind is EnumType:
        return a._set == b._set
    if kind is ArrayType:
        return a.length == b.length and same_checks(a.element, b.element)
    if kind is StructType:
        return a.field_names == b.field_names and all(same_checks(a.fields[n], b.fields[n]) for n in a.field_names)
    return False

# A float field's value sent as it is: a float, or an int that msgpack carries (64 bits); any
# other value takes the field type's `checked_plain`, which checks it (and sends a larger int as
# a float).
_FLOAT_PLAIN = f"({{a}}.__class__ is float or {{a}}.__class__ is int and {INT_MIN} <= {{a}} <= {INT_MAX})"

# `from_checked_plain` of these returns its argument: an array of them is copied as a list
_IDENTITY_BUILDS = (IntType.from_checked_plain, BoolType.from_checked_plain, EnumType.from_checked_plain)


def _compile_struct(struct: StructType) -> None:
    """Straight-line code for a struct's hot paths, the exact equivalent of the generic methods
    (`StructType.checked_plain`, `from_checked_plain`, `Record.__init__` with every field named):
    a number, bool or enum field is checked inline when its value is of the plain class and in
    range, anything else calls the field type's own function, which decides as before."""
    env: dict[str, Any] = {"R": struct.record, "BadValue": BadValue, "slow_check": struct.check,
                           "slow_plain": struct.to_plain, "slow_from": struct.from_plain,
                           "new": object.__new__, "NAMES": frozenset(struct.field_names),
                           "generic_init": Record.__init__, "float": float}
    check, build, init, parse, fill = [], [], [], [], []
    for k, (name, ftype) in enumerate(struct.fields.items()):
        env[f"c{k}"], env[f"b{k}"] = ftype.checked_plain, ftype.from_checked_plain
        env[f"f{k}"] = ftype.from_plain
        kind = type(ftype)
        # from_plain: a field of the plain class and in range is taken as it is (a float made a
        # float); anything else makes the whole value take the generic method, which says what
        parse.append(f"        v{k} = plain[{name!r}]")
        if kind in (IntType, FloatType):
            plain_test = "v{k}.__class__ is int" if kind is IntType else _FLOAT_PLAIN.replace("{a}", "v{k}")
            parse.append(f"        if not ({plain_test.format(k=k)} and lo{k} <= v{k} <= hi{k}) and v{k} is not None:")
            parse.append("            raise BadValue")
        elif kind is BoolType:
            parse.append(f"        if v{k} is not True and v{k} is not False and v{k} is not None:")
            parse.append("            raise BadValue")
        elif kind is EnumType:
            parse.append(f"        if not (v{k}.__class__ is str and v{k} in set{k}) and v{k} is not None:")
            parse.append("            raise BadValue")
        else:
            parse.append(f"        if v{k} is not None:")
            parse.append(f"            v{k} = f{k}(v{k})")
        fill.append(f"        r.{name} = None if v{k} is None else float(v{k})" if kind is FloatType
                    else f"        r.{name} = v{k}")
        check.append(f"        v{k} = value.{name}")
        if kind in (IntType, FloatType):
            env[f"lo{k}"], env[f"hi{k}"] = _range(ftype)
            plain_class = "v{k}.__class__ is int" if kind is IntType else _FLOAT_PLAIN.replace("{a}", "v{k}")
            check.append(f"        if not ({plain_class.format(k=k)} and lo{k} <= v{k} <= hi{k}) and v{k} is not None:")
        elif kind is BoolType:
            check.append(f"        if v{k} is not True and v{k} is not False and v{k} is not None:")
        elif kind is EnumType:
            env[f"set{k}"] = ftype._set
            check.append(f"        if not (v{k}.__class__ is str and v{k} in set{k}) and v{k} is not None:")
        else:
            check.append(f"        if v{k} is not None:")
        check.append(f"            v{k} = c{k}(v{k})")
        build.append(f"        v = plain[{name!r}]")
        if kind in (IntType, BoolType, EnumType):
            build.append(f"        r.{name} = v")  # an unset field (None) included
        elif kind is FloatType:
            build.append(f"        r.{name} = None if v is None else float(v)")
        else:
            build.append(f"        r.{name} = None if v is None else b{k}(v)")
        init.append(f"        self.{name} = fields[{name!r}]")
    items = ", ".join(f"{name!r}: v{k}" for k, name in enumerate(struct.field_names))
    source = "\n".join([
        "def checked_plain(value):",
        "    if value.__class__ is R:",
        "      try:",
        *check,
        f"        return {{{items}}}",
        "      except BadValue:",
        "        pass  # the slow path below says which field, in its words",
        "    slow_check(value)",
        "    return slow_plain(value)",
        "",
        "def from_checked_plain(plain):",
        "    r = new(R)",
        "    try:",
        *(build or ["        pass"]),
        "    except BadValue:  # here or in a field: the slow path says what, from the top",
        "        return slow_from(plain)",
        "    return r",
        "",
        "def from_plain(plain):",
        "    if plain.__class__ is dict and plain.keys() == NAMES:",
        "      try:",
        *parse,
        "        r = new(R)",
        *fill,
        "        return r",
        "      except BadValue:",
        "        pass  # the generic method says which field, in its words",
        "    return slow_from(plain)",
        "",
        "def __init__(self, *args, **fields):",
        "    if not args and fields.keys() == NAMES:",
        *(init or ["        pass"]),
        "    else:",
        "        generic_init(self, *args, **fields)",
    ])
    exec(compile(source, f"<struct {struct.name}>", "exec"), env)
    struct.checked_plain = env["checked_plain"]
    struct.from_checked_plain = env["from_checked_plain"]
    if struct.fields:
        struct.from_plain = env["from_plain"]
    struct.record.__init__ = env["__init__"]


def _compile_array(array: ArrayType) -> None:
    """`checked_plain` of a short array of numbers or bools as one unrolled test: a list of the
    right length whose items all are of the plain class and in range is copied as it is (what
    `to_plain` gives); anything else takes the generic method, which decides as before."""
    element, n = array.element, array.length
    names = [f"a{k}" for k in range(n)]
    if type(element) is BoolType:
        tests = [f"({a} is True or {a} is False)" for a in names]
    else:
        plain = "{a}.__class__ is int" if type(element) is IntType else _FLOAT_PLAIN
        tests = [f"{plain.format(a=a)} and lo <= {a} <= hi" for a in names]
    lo, hi = _range(element) if isinstance(element, _Number) else (-math.inf, math.inf)
    env = {"generic": ArrayType.checked_plain.__get__(array), "generic_from": ArrayType.from_plain.__get__(array),
           "n": n, "lo": lo, "hi": hi}
    unpack = f"        {', '.join(names)}{',' if n == 1 else ''} = value" if n else "        pass"
    # from_plain: a list or tuple of plain items in range, as a fresh list (floats made floats)
    built = f"[{', '.join(f'float({a})' for a in names)}]" if type(element) is FloatType else "list(value)"
    source = "\n".join([
        "def checked_plain(value):",
        "    if value.__class__ is list and len(value) == n:",
        unpack,
        f"        if {' and '.join(tests) or 'True'}:",
        "            return value[:]",
        "    return generic(value)",
        "",
        "def from_plain(value):",
        "    if (value.__class__ is list or value.__class__ is tuple) and len(value) == n:",
        unpack,
        f"        if {' and '.join(tests) or 'True'}:",
        f"            return {built}",
        "    return generic_from(value)",
    ])
    exec(compile(source, f"<array {array.name}>", "exec"), env)
    array.checked_plain = env["checked_plain"]
    array.from_plain = env["from_plain"]
