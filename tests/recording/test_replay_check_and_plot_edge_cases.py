"""Final review of recording, replay and check: defects found by running them on unusual input."""
import copy

import pytest

from echo import PacedEcho
from iotad import Input, Int, Iota, Output, Param
from iotad.recording.conformance import check_trace
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Eager, Engine
from iotad.esprit import load_iota
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import TRACE_SCHEMA, packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from iotad.recording.replay import node_root, replay_node
from recorded_systems import COMPOSITE  # the clocked counter/doubler composite
from recorded_systems import figure2


class Family(Iota):
    N = Param(2)
    S = Param(0.5)
    req = Input(Int(0, None), size="N", switching="S")
    out = Output(Int(0, None), switching="S")

    def init(self):
        self.last = None

    @req.input
    def got(self, i, x):
        self.last = x

    @out.action(value=lambda self: self.last, when=lambda self: self.last is not None)
    def sent(self):
        self.last = None


def test_in_process_spec_holds_this_instances_switching_times_and_sizes(tmp_path):
    """A recorded spec's channel table is the instance's, like a node host's @spec answer:
    switching times and family sizes that name a parameter are stored as numbers."""
    out = tmp_path / "fam.mcap"
    record_run(Family("fam", N=3, S=0.25), out, until=2)
    channels = {c["name"]: c for c in read_recording(out).specs["fam"]["channels"]}
    assert channels["req"]["switching_time"] == 0.25 and channels["req"]["size"] == 3
    assert channels["out"]["switching_time"] == 0.25 and channels["out"]["size"] is None
    out = tmp_path / "echo.mcap"
    record_run(PacedEcho("echo"), out, until=2)
    assert {c["switching_time"] for c in read_recording(out).specs["echo"]["channels"]} == {1.0}


def _composite_node_recording(path):
    """What a node host running a composite root records: every leaf's events on one @trace,
    inputs delivered inside the node (c.tick, d.inp) included."""
    root = load_iota(COMPOSITE, name="clocked", P=2.0)
    engine = Engine(root, VirtualClock(), Eager())
    engine.post(None, "go", None, None, t=1.0)
    engine.run(10)
    sink = McapSink(path)
    sink.add_metadata("iotad.recording", {"system": "s", "clock": "virtual", "time_unit": 1.0})
    sink.add_spec("clocked", {"path": "clocked", "source": {"kind": "esprit", "file": "c.iota", "iota": "clocked"},
                              "text": COMPOSITE, "params": {"P": 2.0}})
    channel = sink.channel("iota/s/clocked/@trace", "iotad.trace_event", TRACE_SCHEMA)
    for k, event in enumerate(engine.trace):
        ns = int(event["t"] * 1e9)
        sink.write(channel, ns, ns, k, packb(event))
    sink.finish()
    assert any(e["iota"] == "clocked/d" and e["kind"] == "input" for e in engine.trace)
    return read_recording(path)


def test_replay_of_a_composite_node_does_not_deliver_its_bound_inputs_twice(tmp_path):
    recording = _composite_node_recording(tmp_path / "composite.mcap")
    result = replay_node(recording, "clocked", 1e-9, ("output", "internal"))
    assert result.ok, "\n".join(result.lines())
    assert len(result.replayed) == len([e for e in recording.trace("clocked") if e["kind"] == "output"])


def test_check_finds_an_output_recorded_as_internal(tmp_path):
    """A firing whose recorded kind is not its channel's direction is not what the spec does."""
    out = tmp_path / "fig2.mcap"
    record_run(figure2(), out, until=30)
    recording = read_recording(out)
    events = copy.deepcopy(recording.trace("scheduler"))
    first = next(e for e in events if e["kind"] == "output")
    first["kind"] = "internal"
    report = check_trace(node_root(recording, "scheduler"), events, node="scheduler", tolerance=1e-9)
    assert not report.ok
    assert report.findings[0].code == "unknown_event"
    events = copy.deepcopy(recording.trace("scheduler"))
    internal = next(e for e in events if e["kind"] == "internal")
    internal["kind"] = "output"
    report = check_trace(node_root(recording, "scheduler"), events, node="scheduler", tolerance=1e-9)
    assert not report.ok


def test_recorder_that_cannot_open_its_session_closes_its_file(tmp_path):
    from iotad.recording.recorder import Recorder
    recorder = Recorder(["iota/x/**"], tmp_path / "r.mcap", listen=["tcp/999.1.1.1:1"])
    with pytest.raises(Exception):
        recorder.start()
    assert recorder.sink._file.closed
    assert read_recording(tmp_path / "r.mcap").complete


def test_plot_of_a_scheduler_with_plain_channels_and_struct_acks(tmp_path):
    from iotad.recording.timeline_plot import plot
    path = tmp_path / "plain.mcap"
    sink = McapSink(path)
    channel = sink.channel("iota/s/sch/@trace", "iotad.trace_event", TRACE_SCHEMA)
    events = [{"t": 0.0, "iota": "sch", "action": "req", "index": None, "kind": "input", "value": {"a": 1}},
              {"t": 0.5, "iota": "sch", "action": "schedule", "index": None, "kind": "internal", "value": None},
              {"t": 1.0, "iota": "sch", "action": "ack", "index": None, "kind": "output", "value": {"code": "COMMIT"}}]
    for k, event in enumerate(events):
        ns = int(event["t"] * 1e9)
        sink.write(channel, ns, ns, k, packb(event))
    sink.finish()
    assert plot(read_recording(path), tmp_path / "plain.png").stat().st_size > 0
