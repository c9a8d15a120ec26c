"""Replay of recordings whose node fired in an order the eager engine would not choose.

- Free replay of a late firing: under load a real process woke up after an input had come in,
  took it, then fired the action that was due before it, and that firing saw the input. Replayed
  on time, the action would fire before the input, with the state before it. Free replay follows
  the recording's order: a firing the recording has after an input waits for that input.
- Free replay of a real-time recording: events within the tolerance agree in either order; a
  virtual-time recording is compared in its exact order.
- A real-time recording by default: each of the node's firings happens at its recorded time, as
  the process's clock chose, and every value is computed again; a value the spec does not
  compute is a divergence."""
import dataclasses

import pytest

from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from system_iotas import Ticker


def late_first_tick(events: list[dict]) -> list[dict]:
    """The trace as a late engine writes it: the tick due at t=1 fired at 1.03, after the input
    of t=1.02, counting it; the echo of that input right after the tick; and every later tick
    0.03 later too, as each counts its time unit from the one before."""
    def at(kind, action, t):
        return next(k for k, e in enumerate(out) if (e["kind"], e["action"], e["t"]) == (kind, action, t))
    out = [dict(e, t=e["t"] + 0.03) if e["action"] == "tick" and e["t"] > 1.5 else e for e in events]
    tick = out.pop(at("output", "tick", 1.0))
    echo_at = at("output", "echo", 1.02)
    out[echo_at] = dict(out[echo_at], t=1.03)
    out.insert(echo_at, dict(tick, t=1.03, value=1))
    return out


@pytest.fixture
def recordings(tmp_path):
    path = tmp_path / "counter.mcap"
    record_run(Ticker("counter"), path, until=3.5,
               inputs=[{"t": 1.02, "action": "inp", "value": 5}, {"t": 2.996, "action": "inp", "value": 7}])
    on_time = read_recording(path)
    late = dataclasses.replace(on_time)
    events = late_first_tick(on_time.trace("counter", starts=True))
    late.trace = lambda node, starts=False: [e for e in events if starts or e["kind"] != "start"]
    return on_time, late


def brief(events):
    return [(e["action"], e["value"], round(e["t"], 6)) for e in events if e["kind"] in ("input", "output")]


def test_the_late_recording_has_the_tick_after_the_input_it_counted(recordings):
    on_time, late = recordings
    assert brief(on_time.trace("counter"))[:3] == [("tick", 0, 1.0), ("inp", 5, 1.02), ("echo", 5, 1.02)]
    assert brief(late.trace("counter"))[:3] == [("inp", 5, 1.02), ("tick", 1, 1.03), ("echo", 5, 1.03)]


def test_the_late_tick_is_replayed_after_the_input_with_its_value(recordings):
    _, late = recordings
    result = replay_node(late, "counter", tolerance=0.02)
    assert result.ok, "\n".join(result.lines())
    assert brief(result.replayed) == [("tick", 1, 1.02), ("echo", 5, 1.02), ("tick", 1, 2.02),
                                      ("echo", 7, 2.996), ("tick", 2, 3.02)]
    assert result.max_time_error == pytest.approx(0.01)


def test_lateness_beyond_the_tolerance_is_still_a_divergence(recordings):
    _, late = recordings
    result = replay_node(late, "counter", tolerance=0.005)
    assert not result.ok
    assert result.divergence == 0 and "beyond the tolerance 0.005" in result.reason


def test_the_on_time_recording_still_replays_exactly(recordings):
    on_time, _ = recordings
    result = replay_node(on_time, "counter", tolerance=0.0)
    assert result.ok, "\n".join(result.lines())
    assert [e["value"] for e in result.replayed] == [0, 5, 1, 7, 2]


def swapped_at_three(events: list[dict]) -> list[dict]:
    """The trace of a real process whose clock woke it up for the tick due at t=3 just before it
    echoed the input of t=2.996 (jitter of a few ms swapped them; the tick counts the input
    either way)."""
    out = list(events)
    k = next(k for k, e in enumerate(out) if (e["kind"], e["action"], e["t"]) == ("output", "echo", 2.996))
    echo = out.pop(k)
    tick = next(k for k, e in enumerate(out) if (e["kind"], e["action"], e["t"]) == ("output", "tick", 3.0))
    out[tick] = dict(out[tick], t=2.999)
    out.insert(tick + 1, dict(echo, t=3.001))
    return out


@pytest.mark.parametrize("clock, agrees", [("real", True), ("virtual", False)])
def test_a_real_time_recording_agrees_in_either_order_within_the_tolerance(recordings, clock, agrees):
    on_time, _ = recordings
    swapped = dataclasses.replace(on_time, metadata={**on_time.metadata,
                                                     "iotad.recording": {**on_time.metadata["iotad.recording"],
                                                                         "clock": clock}})
    events = swapped_at_three(on_time.trace("counter", starts=True))
    swapped.trace = lambda node, starts=False: [e for e in events if starts or e["kind"] != "start"]
    assert brief(swapped.trace("counter"))[-3:] == [("inp", 7, 2.996), ("tick", 2, 2.999), ("echo", 7, 3.001)]
    result = replay_node(swapped, "counter", tolerance=0.01, guided=False)
    assert result.ok is agrees, "\n".join(result.lines())
    if agrees:
        assert result.reordered == 1 and "1 in another order than the replay's" in result.lines()[0]
    else:  # a virtual-time recording has the order exactly
        assert result.divergence == 3 and "a free re-run of a real-time recording" not in "\n".join(result.lines())


def as_real_time(recording, events):
    """`recording` read as a real-time one whose trace for the counter is `events`."""
    real = dataclasses.replace(recording, metadata={**recording.metadata, "iotad.recording": {
        **recording.metadata["iotad.recording"], "clock": "real"}})
    real.trace = lambda node, starts=False: [e for e in events if starts or e["kind"] != "start"]
    return real


def test_a_real_time_recording_is_replayed_at_its_recorded_firing_times(recordings):
    on_time, _ = recordings
    events = late_first_tick(on_time.trace("counter", starts=True))
    result = replay_node(as_real_time(on_time, events), "counter", tolerance=0.01)
    assert result.ok and result.guided, "\n".join(result.lines())
    assert [(e["action"], e["value"], e["t"]) for e in result.replayed] == [
        (e["action"], e["value"], e["t"]) for e in events if e["kind"] == "output"]   # times too, exactly
    assert "each firing at its recorded time" in result.lines()[0]


def test_a_value_the_spec_does_not_compute_diverges_at_the_recorded_times(recordings):
    on_time, _ = recordings
    events = [dict(e, value=9) if (e["action"], e["t"]) == ("tick", 2.0) else e
              for e in on_time.trace("counter", starts=True)]
    result = replay_node(as_real_time(on_time, events), "counter", tolerance=0.01)
    assert not result.ok and result.guided
    assert result.reason == "recorded output tick=9 at t=2, replayed output tick=1 at t=2"
    assert "says which rule of the spec it breaks" in result.lines()[-1]
