"""A port that built an input's plain value with its type's checks marks it (`CheckedPlain`): the
CAN port's frames, which the bus's receive built with `Frame`'s checks. The engine then builds the
value without checking it again and records the plain value as it came. The mark is believed only
for an input whose own type checks the same: on any other input the value is checked as usual."""
import pytest

from iotad import Engine, Input, Iota, VirtualClock
from iotad.can.burst_types import CAN_FRAMES
from iotad.can.frame import CAN_FRAME
from iotad.kernel.types import CheckedPlain, Int


class Listener(Iota):
    can_rx = Input(CAN_FRAME, switching=0)
    can_rx_burst = Input(CAN_FRAMES, switching=0)
    count = Input(Int(0, 10), switching=0)

    def init(self):
        self.heard = []

    @can_rx.input
    def got_frame(self, value):
        self.heard.append((value.id, list(value.data)))

    @can_rx_burst.input
    def got_frames(self, frames):
        self.heard.extend((value.id, list(value.data)) for value in frames)

    @count.input
    def got_count(self, value):
        self.heard.append(value)


def frame(ident: int) -> dict:
    return {"id": ident, "extended": False, "rtr": False, "dlc": 2, "data": [ident & 0xFF, 7, 0, 0, 0, 0, 0, 0]}


def run(*posts):
    node = Listener("listener")
    engine = Engine(node, VirtualClock())
    for t, channel, value, meta in posts:
        engine.post(None, channel, value, t=t, meta=meta)
    engine.run(1.0)
    return engine, node.heard


@pytest.fixture
def checks_fail(monkeypatch):
    """canFrame's checks made to fail: what still gets through was not checked again."""
    def refuse(plain):
        raise AssertionError("checked again")
    monkeypatch.setattr(CAN_FRAME, "from_plain", refuse)


def test_a_marked_frame_is_taken_without_its_checks_and_recorded_as_it_came(checks_fail):
    one, burst = frame(0x29), [frame(0x49), frame(0x69)]
    engine, heard = run((0.1, "can_rx", one, CheckedPlain(CAN_FRAME)),
                        (0.2, "can_rx_burst", burst, CheckedPlain(CAN_FRAMES)))
    assert heard == [(0x29, [0x29, 7, 0, 0, 0, 0, 0, 0]), (0x49, [0x49, 7, 0, 0, 0, 0, 0, 0]),
                     (0x69, [0x69, 7, 0, 0, 0, 0, 0, 0])]
    inputs = [e for e in engine.trace if e["kind"] == "input"]
    assert [(e["action"], e["value"]) for e in inputs] == [("can_rx", one), ("can_rx_burst", burst)]
    assert not [e for e in engine.trace if e["kind"] == "violation"]


def test_an_unmarked_frame_is_checked(checks_fail):
    engine, heard = run((0.1, "can_rx", frame(0x29), None))
    assert heard == []
    [violation] = [e["value"] for e in engine.trace if e["kind"] == "violation"]
    assert violation["violation"] == "bad_value" and "checked again" in violation["message"]


def test_a_mark_for_another_type_is_not_believed():
    engine, heard = run((0.1, "count", frame(0x29), CheckedPlain(CAN_FRAME)),
                        (0.2, "count", 11, CheckedPlain(CAN_FRAME)), (0.3, "count", 3, None))
    assert heard == [3]
    violations = [(e["t"], e["value"]["violation"]) for e in engine.trace if e["kind"] == "violation"]
    assert violations == [(0.1, "bad_value"), (0.2, "bad_value")]
