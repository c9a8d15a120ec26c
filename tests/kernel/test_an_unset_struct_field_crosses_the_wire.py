"""A struct field may be unset (None, NULL in the paper) until assigned: `check` lets it through,
so it goes out on the wire as null and must come in as None, by the fast path and the slow one
alike. The case that needs it: a real bus's log (`canBusFrame`, whose `station` a real bus never
tells) bound into another IOTA's input."""
import pytest

from iotad.can.frame import Frame
from iotad.can.frame_log import CAN_BUS_FRAME, bus_frame
from iotad.node_host import wire
from iotad.kernel.types import Array, BadValue, Float, Int, Struct

POINT = Struct("point", x=Float, y=Float(0, 1), n=Int(0, 9))
PATH = Struct("path", start=POINT, steps=Array(Int(0, 9), 2), gain=Float)


def through_the_wire(struct, value):
    plain = wire.decode(wire.encode(struct.checked_plain(value)))
    return struct.from_checked_plain(plain), struct.from_plain(plain)


def test_a_real_bus_s_log_entry_without_its_station_comes_in_as_sent():
    entry = bus_frame(Frame(0x123, b"\x01\x02").to_value(), None, 6.2e-5)
    fast, slow = through_the_wire(CAN_BUS_FRAME, entry)
    for got in (fast, slow):
        assert got.station is None and got.id == 0x123 and got.dlc == 2 and list(got.data[:2]) == [1, 2]
        assert CAN_BUS_FRAME.to_plain(got) == CAN_BUS_FRAME.to_plain(entry)


def test_unset_fields_of_every_kind_stay_unset_and_set_ones_are_still_checked():
    value = PATH(start=None, steps=None, gain=None)
    for got in through_the_wire(PATH, value):
        assert (got.start, got.steps, got.gain) == (None, None, None)
    inner = PATH(start=POINT(x=None, y=0.5, n=None), steps=[1, 2], gain=2.0)
    for got in through_the_wire(PATH, inner):
        assert (got.start.x, got.start.y, got.start.n, list(got.steps), got.gain) == (None, 0.5, None, [1, 2], 2.0)
    with pytest.raises(BadValue, match="path.gain"):
        PATH.from_plain({"start": None, "steps": None, "gain": "fast"})
