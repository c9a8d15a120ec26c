"""The engine's value shortcuts (`checked_plain`, `from_checked_plain`, a struct's compiled code)
must give what the slow pairs give: the same plain data (same classes: an int stays an int),
the same values built back, the same `BadValue` message, for good and bad values alike."""
import math
import random

import pytest

from iotad.kernel.types import Array, ArrayType, BadValue, Bool, Enum, Float, Int, Record, Struct, StructType, Type

COLOUR = Enum("colour", "RED", "GREEN")
INNER = Struct("inner", x=Float(-1, 1), n=Int(0, 9))
OUTER = Struct("outer", id=Int(0, 0x7FF), on=Bool, gain=Float, ratio=Float(0, 1), colour=COLOUR,
               data=Array(Int(0, 255), 3), points=Array(INNER, 2), inner=INNER, samples=Array(Float, 2))
ODD = Struct("odd", **{"class": Int, "ok": Bool})  # a field name the compiled code cannot spell


class MyInt(int):
    pass


class MyFloat(float):
    pass


ODDITIES = [None, "x", True, 1.5, -3, 10 ** 6, math.nan, math.inf, -math.inf, MyInt(3), MyFloat(0.5),
            [], (1, 2), 0, 0.25, "RED", 1 << 64, 1 << 70, -(1 << 70), 1 << 2000]


def value_of(t, rng, odd):
    """A value for `t`: each part is an oddity (maybe fine, maybe not) with probability `odd`."""
    if rng.random() < odd:
        return rng.choice(ODDITIES + [INNER(), {"x": 1}])
    if t is COLOUR:
        return rng.choice(["RED", "GREEN"])
    if isinstance(t, type(OUTER)):
        return t.record(**{name: value_of(ft, rng, odd) for name, ft in t.fields.items()})
    if isinstance(t, type(OUTER.fields["data"])):
        items = [value_of(t.element, rng, odd) for _ in range(t.length)]
        return tuple(items) if rng.random() < 0.1 else items
    if t is Bool:
        return rng.choice([True, False])
    low = -5 if t.low is None else t.low
    high = 5 if t.high is None else t.high
    number = rng.uniform(low, high)
    return int(number) if isinstance(t, type(Int)) or rng.random() < 0.2 else number


def outcome(fn, *args):
    try:
        return "ok", shape(fn(*args))
    except BadValue as exc:
        return "bad", str(exc)
    except (TypeError, AttributeError) as exc:
        return "error", type(exc).__name__


def shape(value):
    """What a value is, classes included (1 and 1.0 differ), records by type and fields."""
    if isinstance(value, Record):
        return (value._type.name, tuple((n, shape(getattr(value, n))) for n in value._type.field_names))
    if isinstance(value, dict):
        return ("dict", tuple((k, shape(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(shape(v) for v in value))
    return (type(value).__name__, repr(value))


@pytest.mark.parametrize("t", [OUTER, INNER, COLOUR, Float(0, 1), Int(0, 255), Bool, Array(Float, 2), ODD],
                         ids=lambda t: t.name)
def test_checked_plain_and_back_agree_with_check_to_plain_and_from_plain(t):
    rng = random.Random(t.name)
    checked = 0
    for _ in range(3000):
        value = ODD.record(**{"class": rng.choice([1, "x", None]), "ok": rng.choice([True, 2])}) \
            if t is ODD else value_of(t, rng, rng.choice([0.0, 0.01, 0.1, 0.5]))
        fast = outcome(t.checked_plain, value)
        slow = outcome(lambda v: Type.checked_plain(t, v), value)  # check, then to_plain
        assert fast == slow, value
        if fast[0] != "ok":
            continue
        checked += 1
        plain = Type.checked_plain(t, value)
        built, reference = outcome(t.from_checked_plain, plain), outcome(t.from_plain, plain)
        assert built == reference, plain
        if built[0] == "ok" and isinstance(plain, (list, dict)):
            assert t.from_checked_plain(plain) is not plain  # a fresh value, never the sender's
    assert checked > 100  # good values were tried, not only bad ones


def test_a_built_array_is_never_the_plain_list():
    data = [1, 2, 3]
    built = OUTER.fields["data"].from_checked_plain(data)
    assert built == data and built is not data


def test_records_built_with_every_field_named_or_not_are_the_same():
    full = INNER(x=0.5, n=3)
    assert shape(full) == shape(INNER(0.5, 3)) == shape(INNER(n=3, x=0.5))
    assert shape(INNER(x=0.5)) == shape(INNER(x=0.5, n=0))  # a missing field takes its default
    with pytest.raises(TypeError, match="no field"):
        INNER(x=0.5, n=3, y=1)
    with pytest.raises(TypeError, match="at most 2 positional"):
        INNER(1, 2, 3)


def test_types_spelled_the_same_check_the_same_and_build_the_same():
    """Two loads of one ESPRIT file make two struct types with the same fields: an output of
    one is delivered to an input of the other without checking again (`same_checks`)."""
    from iotad.kernel.types import same_checks
    twin_inner = Struct("inner", x=Float(-1, 1), n=Int(0, 9))
    twin = Struct("outer", id=Int(0, 0x7FF), on=Bool, gain=Float, ratio=Float(0, 1),
                  colour=Enum("colour", "GREEN", "RED"), data=Array(Int(0, 255), 3), points=Array(twin_inner, 2),
                  inner=twin_inner, samples=Array(Float, 2))
    assert same_checks(OUTER, twin) and same_checks(twin, OUTER)
    assert not same_checks(INNER, Struct("inner", x=Float(-1, 2), n=Int(0, 9)))  # a wider range
    assert not same_checks(INNER, Struct("inner", n=Int(0, 9), x=Float(-1, 1)))  # another order
    assert not same_checks(Float, Int) and not same_checks(Array(Int, 2), Array(Int, 3))
    assert not same_checks(COLOUR, Enum("colour", "RED")) and not same_checks(None, Int)
    rng = random.Random(11)
    for _ in range(2000):
        value = value_of(OUTER, rng, rng.choice([0.0, 0.05]))
        try:
            plain = OUTER.checked_plain(value)
        except (BadValue, TypeError):  # TypeError: an unhashable value for the enum (as check does)
            continue
        assert outcome(twin.from_checked_plain, plain) == outcome(twin.from_plain, plain)


def plain_of(t, rng, odd):
    """A plain value for `t` as a payload brings it: a dict for a struct (a key missing or extra
    now and then), a list or tuple for an array; each part an oddity with probability `odd`."""
    if rng.random() < odd:
        return rng.choice(ODDITIES + [{"x": 1}, {"x": 0.5, "n": 3, "y": 1}])
    if isinstance(t, type(OUTER)):
        plain = {name: plain_of(ft, rng, odd) for name, ft in t.fields.items()}
        if rng.random() < odd:
            plain.pop(rng.choice(list(plain)))
        return plain
    if isinstance(t, type(OUTER.fields["data"])):
        items = [plain_of(t.element, rng, odd) for _ in range(t.length + (rng.random() < odd))]
        return tuple(items) if rng.random() < 0.2 else items
    return value_of(t, rng, odd)


@pytest.mark.parametrize("t", [OUTER, INNER, Array(Float, 2), Array(Int(0, 255), 8), Array(Bool, 3), ODD],
                         ids=lambda t: t.name)
def test_from_plain_agrees_with_the_generic_method(t):
    """What an input's payload becomes: the compiled `from_plain` of a struct or a short array
    of numbers builds what the generic method builds, and refuses with its words."""
    generic = {StructType: StructType.from_plain, ArrayType: ArrayType.from_plain}[type(t)]
    rng = random.Random(f"plain {t.name}")
    taken = 0
    for _ in range(3000):
        plain = plain_of(t, rng, rng.choice([0.0, 0.01, 0.1, 0.5]))
        fast, slow = outcome(t.from_plain, plain), outcome(lambda p: generic(t, p), plain)
        assert fast == slow, plain
        taken += fast[0] == "ok"
        if fast[0] == "ok" and isinstance(plain, (list, dict)):
            assert t.from_plain(plain) is not plain  # a fresh value, never the payload's
    assert taken > 100
