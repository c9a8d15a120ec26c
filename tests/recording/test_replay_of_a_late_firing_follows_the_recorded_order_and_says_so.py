"""Free replay (`iotad replay --free`) of a real-time recording in which a firing came later than
the tolerance: the replay fired it on time, before the events the recording has between, so it
was compared out of order (a Buggy recording's `body` diverged at output #17 with "recorded
proximity, replayed can_tx", the world's late physics step the cause). Now the late firing is
replayed where the recording has it, at its recorded time, and the replay says how late it came;
and where a value differs, the replay is still compared in the recorded order: the same channel
against the same channel, not another event in its place."""
import dataclasses

import pytest

from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from system_iotas import Ticker

LATE = 0.05  # beyond the tolerance, 0.01


@pytest.fixture
def on_time(tmp_path):
    path = tmp_path / "counter.mcap"
    record_run(Ticker("counter"), path, until=3.5,
               inputs=[{"t": 1.02, "action": "inp", "value": 5}, {"t": 2.996, "action": "inp", "value": 7}])
    return read_recording(path)


def real_time(recording, events):
    real = dataclasses.replace(recording, metadata={**recording.metadata, "iotad.recording": {
        **recording.metadata["iotad.recording"], "clock": "real"}})
    real.trace = lambda node, starts=False: [e for e in events if starts or e["kind"] != "start"]
    return real


def late_tick(events):
    """The process woke up LATE after the tick due at t=1: the input of 1.02 came first and the
    tick counted it; the echo of the input came right after the tick; every later tick counts
    its time unit from the late one."""
    out = []
    for event in events:
        if (event["kind"], event["action"], event["t"]) == ("output", "tick", 1.0):
            continue
        if event["action"] == "tick" and event["t"] > 1.5:
            event = dict(event, t=event["t"] + LATE)
        if (event["kind"], event["action"], event["t"]) == ("output", "echo", 1.02):
            out.append({"t": 1.0 + LATE, "iota": "counter", "action": "tick", "index": None, "kind": "violation",
                        "value": {"violation": "deadline_miss", "message": "tick fired late"}})
            out.append({"t": 1.0 + LATE, "iota": "counter", "action": "tick", "index": None, "kind": "output",
                        "value": 1})
            event = dict(event, t=1.0 + LATE)
        out.append(event)
    return out


def brief(events):
    return [(e["action"], e["value"], round(e["t"], 6)) for e in events if e["kind"] == "output"]


def test_a_late_firing_is_replayed_where_the_recording_has_it_and_its_lateness_is_said(on_time):
    events = late_tick(on_time.trace("counter", starts=True))
    recording = real_time(on_time, events)
    result = replay_node(recording, "counter", tolerance=0.01, guided=False)
    assert result.ok, "\n".join(result.lines())
    assert brief(result.replayed) == brief(events) == [
        ("tick", 1, 1.05), ("echo", 5, 1.05), ("tick", 1, 2.05), ("echo", 7, 2.996), ("tick", 2, 3.05)]
    assert [(e["action"], round(e["t"], 6), due) for e, due in result.late] == [
        ("tick", 1.05, 1.0), ("echo", 1.05, 1.02)]
    lines = "\n".join(result.lines())
    assert "2 firing(s) came later than the tolerance after the replay has them due, and are replayed " \
        "where the recording has them" in lines
    assert "the first, output tick=1 at t=1.05 (it was due at t=1, 0.05 late)" in lines


def test_the_default_replay_at_the_recorded_times_says_which_came_after_their_windows_closed(on_time):
    events = late_tick(on_time.trace("counter", starts=True))
    result = replay_node(real_time(on_time, events), "counter", tolerance=0.01)
    assert result.ok and result.guided, "\n".join(result.lines())
    assert [(e["action"], round(e["t"], 6), due) for e, due in result.late] == [("tick", 1.05, 1.0)]
    assert "1 firing(s) came later than the tolerance after their windows closed; the first, output tick=1 " \
        "at t=1.05 (its window closed at t=1, 0.05 late)" in result.lines()[1]


def test_a_value_that_differs_is_compared_in_the_recorded_order(on_time):
    """A real process's clock swapped the tick due at 3 and the echo of the input of 2.996 (within
    the tolerance) and its tick says 9, which the spec never computes: the replay names the
    tick against the tick, not the echo in its place."""
    events = list(on_time.trace("counter", starts=True))
    k = next(k for k, e in enumerate(events) if (e["kind"], e["action"], e["t"]) == ("output", "echo", 2.996))
    echo = events.pop(k)
    tick = next(k for k, e in enumerate(events) if (e["kind"], e["action"], e["t"]) == ("output", "tick", 3.0))
    events[tick] = dict(events[tick], t=2.999, value=9)
    events.insert(tick + 1, dict(echo, t=3.001))
    result = replay_node(real_time(on_time, events), "counter", tolerance=0.01, guided=False)
    assert not result.ok
    assert result.reason == "recorded output tick=9 at t=2.999, replayed output tick=2 at t=3", result.reason


def test_a_virtual_time_recording_is_still_compared_exactly(on_time):
    events = late_tick(on_time.trace("counter", starts=True))
    virtual = dataclasses.replace(on_time)
    virtual.trace = lambda node, starts=False: [e for e in events if starts or e["kind"] != "start"]
    result = replay_node(virtual, "counter", tolerance=0.01, guided=False)
    assert not result.ok and result.divergence == 0 and "beyond the tolerance 0.01" in result.reason
    assert result.late == []
