"""The node host's @trace: published in bursts, opened by an engine-start record that recordings,
the checker and replay use for the start of the first windows (older recordings still read)."""
import json

from iotad.node_host import wire
from iotad.recording.conformance import check_trace, split_start
from iotad.node_host.host_clock import HostClock
from iotad.recording.recorder import yield_cpu
from iotad.recording.mcap_reader import read_recording, start_time
from iotad.recording.mcap_sink import McapSink
from scheduler import Scheduler


class Buffer:
    def __init__(self, pending=0):
        self.pending, self.flushes = pending, 0

    def flush(self):
        self.flushes += 1
        self.pending = 0


def test_trace_waits_for_its_period_not_for_each_block():
    buffer = Buffer(pending=3)
    clock = HostClock(heartbeat_period=100.0, flush=buffer.flush, pending=lambda: buffer.pending,
                      trace_period=100.0)
    clock._next_beat = clock.now() + 100.0  # no heartbeat in this test
    assert clock.wait(clock.now() + 0.01) is None  # blocked until the deadline...
    assert buffer.flushes == 0                       # ...without publishing the trace
    clock._trace_due = clock.now()                   # the period is over:
    assert clock.wait(clock.now()) is None           # a firing due now goes first,
    assert buffer.flushes == 0
    assert clock.wait(clock.now() + 0.01) is None    # the trace goes out before blocking
    assert buffer.flushes == 1


def test_trace_period_zero_flushes_before_each_block_and_a_flood_flushes_at_once():
    buffer = Buffer(pending=1)
    clock = HostClock(heartbeat_period=100.0, flush=buffer.flush, pending=lambda: buffer.pending)
    clock._next_beat = clock.now() + 100.0
    # a deadline still ahead when wait() looks (a 1 ms one had passed on a loaded machine, and a
    # firing due goes first, unflushed): it blocks until then, flushing first
    clock.wait(clock.now() + 0.3)
    assert buffer.flushes == 1
    buffer.pending = HostClock.TRACE_BATCH
    clock._trace_due = clock.now() + 100.0
    clock.post("item")
    assert clock.wait(clock.now() + 100.0) == "item"  # an input waiting: no block, but a full buffer
    assert buffer.flushes == 2


def _recording_with(tmp_path, events, spec):
    sink = McapSink(tmp_path / "r.mcap")
    sink.add_spec("scheduler", spec)
    topic = wire.trace_key("sys", "scheduler")
    channel = sink.channel(topic, "iotad.trace_event", {})
    for seq, event in enumerate(events):
        sink.write(channel, seq, seq, seq, wire.encode(event))
    sink.finish()
    return read_recording(tmp_path / "r.mcap")


def test_recording_reads_the_start_event_and_keeps_it_out_of_the_trace(tmp_path):
    spec = {"path": "scheduler", "source": {}, "origin": 100.0, "started": 100.5, "time_unit": 1.0}
    start = wire.start_event(0.75, "scheduler", 100.75, 123)
    event = {"t": 1.0, "iota": "scheduler", "action": "req", "index": 0, "kind": "input", "value": None}
    recording = _recording_with(tmp_path, [start, event], spec)
    assert [e["kind"] for e in recording.trace("scheduler")] == ["input"]
    assert [e["kind"] for e in recording.trace("scheduler", starts=True)] == ["start", "input"]
    assert recording.start_times() == {"scheduler": 0.75}
    assert start_time(recording.specs["scheduler"]) == 0.75  # exact, not the @spec stamp (0.5)
    json.dumps(recording.specs)


def test_old_recordings_without_start_event_use_the_spec_stamp(tmp_path):
    spec = {"path": "scheduler", "source": {}, "origin": 100.0, "started": 100.5, "time_unit": 1.0}
    event = {"t": 1.0, "iota": "scheduler", "action": "req", "index": 0, "kind": "input", "value": None}
    recording = _recording_with(tmp_path, [event], spec)
    assert recording.start_times() == {}
    assert start_time(recording.specs["scheduler"]) == 0.5


def test_checker_takes_the_start_from_a_start_event():
    events = [wire.start_event(2.0, "scheduler", 0.0, 1)]
    rest, start = split_start(events, 0.0)
    assert rest == [] and start == 2.0
    assert split_start([], 1.5) == ([], 1.5)
    report = check_trace(Scheduler("scheduler", N=2, T=0.5), events, node="scheduler")
    assert report.ok


def test_yield_cpu_on_an_unknown_thread_changes_nothing():
    assert yield_cpu([2**22 + 12345]) == "unchanged"  # no such thread: no error either
