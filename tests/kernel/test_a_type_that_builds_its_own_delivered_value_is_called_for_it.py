"""The engine hands a delivered value on without a call where the type promises that its checked
plain value is the value itself (`checked_plain_is_value`: an int, a bool, an enum's name). A
subclass that builds its values another way (its own `from_checked_plain`) does not inherit the
promise: its receivers get what it builds."""
from iotad import Composite, Engine, Input, Iota, Output
from iotad.kernel.types import BoolType, EnumType, FloatType, IntType, StructType


class Box:
    def __init__(self, n):
        self.n = n


class BoxedInt(IntType):
    """An int on the wire, a `Box` in the IOTA."""

    def from_plain(self, plain):
        self.check(plain)
        return Box(plain)

    def from_checked_plain(self, plain):
        return Box(plain)

    def to_plain(self, value):
        return value.n if isinstance(value, Box) else value


class PlainSubclass(IntType):
    """An int type with nothing of its own about delivery."""


BOXED = BoxedInt()


class Sender(Iota):
    out = Output(BOXED)

    def init(self):
        self.n = 0

    @out.action(value=lambda self: self.n, when=lambda self: self.n < 3, after=1.0)
    def send(self):
        self.n += 1


class Receiver(Iota):
    inp = Input(BOXED)

    def init(self):
        self.got = []

    @inp.input
    def take(self, x):
        self.got.append(x)


def test_a_subclass_with_its_own_from_checked_plain_gets_its_built_value_delivered():
    engine = Engine(Composite("pair", Sender("s"), Receiver("r"), bind=[("s.out", "r.inp")]))
    engine.run(10)
    got = engine.iota("pair/r").got
    assert [type(x) for x in got] == [Box, Box, Box] and [x.n for x in got] == [0, 1, 2]
    # the trace holds the plain ints either way
    assert [e["value"] for e in engine.trace if e["kind"] == "input"] == [0, 1, 2]


def test_only_types_whose_checked_plain_value_is_the_value_make_the_promise():
    assert IntType().checked_plain_is_value and BoolType().checked_plain_is_value
    assert EnumType("a", "b").checked_plain_is_value and PlainSubclass().checked_plain_is_value
    assert not BoxedInt().checked_plain_is_value
    assert not FloatType().checked_plain_is_value  # an int sent as a float arrives as a float
    assert not StructType("s", x=IntType()).checked_plain_is_value
