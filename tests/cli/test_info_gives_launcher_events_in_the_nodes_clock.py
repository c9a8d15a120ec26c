"""`iotad info` gives the launcher's events (a node live, exited, restarted) in the nodes' clock,
the one every trace event, violation and `iotad check` line is in: seconds from the system's
origin, not from the recording's first message (which came a fraction of a second later)."""
from iotad.cli import main
from iotad.node_host import wire
from iotad.recording.mcap_sink import McapSink


def test_a_launcher_event_is_timed_as_the_nodes_events_are(tmp_path, capsys):
    out = tmp_path / "r.mcap"
    sink = McapSink(out)
    sink.add_metadata("iotad.recording", {"system": '"s"', "clock": '"real"'})
    sink.add_spec("n", {"path": "n", "source": {}, "origin": 100.0, "started": 100.2, "time_unit": 1.0})
    trace = sink.channel(wire.trace_key("s", "n"), "iotad.trace_event", {})
    launcher = sink.channel(wire.launcher_key("s"), "iotad.launcher_event", {})
    start = wire.start_event(0.25, "n", 100.25, 7)  # the node's engine started at t=0.25
    sink.write(trace, int(100.3e9), int(100.3e9), 0, wire.encode(start))
    live = {"event": "live", "node": "n", "pid": 7, "code": None, "t_ns": int(100.5e9), "restarts": 0}
    sink.write(launcher, int(100.5e9), int(100.5e9), 0, wire.encode(live))
    sink.finish()
    assert main(["info", str(out)]) == 0
    lines = [line.strip() for line in capsys.readouterr().out.splitlines()]
    live_lines = [line for line in lines if line.endswith("pid 7")]
    assert len(live_lines) == 1 and live_lines[0].startswith("0.500 s  live"), lines  # t=0.5, not 0.2
