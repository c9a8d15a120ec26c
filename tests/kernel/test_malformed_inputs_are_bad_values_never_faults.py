"""What arrives on an input is checked before anything else: a payload its type cannot read is a
recorded `bad_value` (also a list for an enum, which once crashed a node with TypeError), a
value on an input that carries none is one too, and a malformed payload that also came too
early is reported as malformed, so that the record tells it from a well-formed early one."""
import pytest

from iotad import Engine, Input, Iota, VirtualClock
from iotad.kernel.types import Enum, Struct, Float

ACK = Enum("ack", "COMMIT", "ABORT")
POSE = Struct("pose", x=Float, y=Float)


class Listener(Iota):
    ack = Input(ACK, switching=1.0)
    pose = Input(POSE)
    poke = Input()

    def init(self):
        self.heard = []

    @ack.input
    def got_ack(self, value):
        self.heard.append(value)

    @poke.input
    def got_poke(self, _):
        self.heard.append("poke")


def deliver(*inputs):
    """(t, channel, value) inputs into a fresh Listener; its violations and what it heard."""
    node = Listener("listener")
    engine = Engine(node, VirtualClock())
    for t, channel, value in inputs:
        engine.post("listener", channel, value, t=t)
    engine.run(10)
    violations = [(e["t"], e["action"], e["value"]["violation"], e["value"]["message"])
                  for e in engine.trace if e["kind"] == "violation"]
    return violations, node.heard


@pytest.mark.parametrize("value", [[1, 2], {"a": 1}, 3, None, "BOGUS"])
def test_what_is_not_an_enum_member_is_a_bad_value_and_the_node_goes_on(value):
    violations, heard = deliver((1.0, "ack", value), (3.0, "ack", "COMMIT"))
    assert [(t, channel, code) for t, channel, code, _ in violations] == [(1.0, "ack", "bad_value")]
    assert "is not a member of enum ack" in violations[0][3] and violations[0][3].endswith("; rejected")
    assert heard == ["COMMIT"]


def test_a_value_on_an_input_that_carries_none_is_a_bad_value():
    violations, heard = deliver((1.0, "poke", 5), (2.0, "poke", None))
    assert violations == [(1.0, "poke", "bad_value", "input poke carries no value, got 5; rejected")]
    assert heard == ["poke"]


def test_a_malformed_payload_that_came_too_early_is_reported_as_malformed():
    violations, heard = deliver((1.0, "ack", "COMMIT"), (1.5, "ack", [1]), (1.6, "ack", "ABORT"))
    assert [(t, code) for t, _, code, _ in violations] == [(1.5, "bad_value"), (1.6, "switching_time")]
    assert heard == ["COMMIT"]


def test_a_struct_of_the_wrong_shape_is_a_bad_value():
    violations, _ = deliver((1.0, "pose", [1.0, 2.0]), (2.0, "pose", {"x": 1.0}), (3.0, "pose", {"x": "a", "y": 1}))
    assert [code for _, _, code, _ in violations] == ["bad_value"] * 3
