"""A NaN inside a message's value (a list or a map of floats: a sensor that had no reading) is
the same value on every account of the message: the sender's claim, the wire and the receiver's
input that all hold `[1.0, nan]` or `{"x": nan}` are one delivery, not an 'altered' message.
(NaN is unequal to itself in Python, and inside a list or a map `==` compares it that way.)"""
import pytest

from iotad.recording.delivery import check_delivery
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from recorded_systems import figure2
from wire_tamper import rewrite, with_value

NAN = float("nan")
SENDER, RECEIVER, WIRE = "iota/figure2/scheduler/@trace", "iota/figure2/vision/@trace", "iota/figure2/scheduler/ack/0"


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    path = tmp_path_factory.mktemp("nan") / "fig2.mcap"
    record_run(figure2(), path, until=20)
    return path


def carrying(value, nth=0):
    """The `nth` ack to vision, on all three accounts (claim, wire, receipt), changed to `value`."""
    def change(messages):
        claims = [k for k, m in enumerate(messages) if m.topic == SENDER and m.value.get("kind") == "output"
                  and m.value.get("action") == "ack" and m.value.get("index") == 0]
        t = messages[claims[nth]].value["t"]
        for k, message in enumerate(messages):
            event = message.value if message.topic in (SENDER, RECEIVER) else None
            if event is not None and event.get("action") == "ack" and event.get("t") == t \
                    and (message.topic == RECEIVER or event.get("index") == 0):
                messages[k] = with_value(message, dict(event, value=value))
        wire = [k for k, m in enumerate(messages) if m.topic == WIRE]
        messages[wire[nth]] = with_value(messages[wire[nth]], value)
        return messages
    return change


@pytest.mark.parametrize("value", [[1.0, NAN], {"x": NAN}, {"readings": [{"x": NAN}, {"x": 2.0}]}],
                         ids=["list", "map", "nested"])
def test_the_same_nested_nan_on_every_account_is_delivered(clean, tmp_path, value):
    before = check_delivery(read_recording(clean))
    after = check_delivery(read_recording(rewrite(clean, tmp_path / "nan.mcap", carrying(value))))
    assert before.ok and after.ok, [str(f) for f in after.findings]
    assert after.totals() == before.totals() and after.totals(wire=True) == before.totals(wire=True)


def test_a_nan_that_became_a_number_is_still_altered(clean, tmp_path):
    def change(messages):
        messages = carrying([1.0, NAN])(messages)
        k = [k for k, m in enumerate(messages) if m.topic == WIRE][0]
        messages[k] = with_value(messages[k], [1.0, 0.0])
        return messages

    report = check_delivery(read_recording(rewrite(clean, tmp_path / "changed.mcap", change)))
    assert [f.code for f in report.findings if f.problem] == ["altered"]
    assert "the wire carried [1.0, 0.0]" in report.findings[0].message


def test_values_equal_is_exact_and_values_close_is_tolerant():
    from iotad.recording.values import values_close, values_equal

    assert values_equal([1.0, NAN], [1.0, NAN]) and values_equal({"x": [NAN]}, {"x": [NAN]})
    assert values_equal(NAN, NAN) and values_equal(1, 1.0)
    assert not values_equal([1.0, NAN], [1.0, 0.0]) and not values_equal({"x": NAN}, {"y": NAN})
    assert not values_equal(1.0, 1.0 + 1e-12) and values_close(1.0, 1.0 + 1e-12)
    assert not values_close([1.0], [1.0, 2.0]) and values_close({"x": [1.0]}, {"x": [1.0 + 1e-12]})
