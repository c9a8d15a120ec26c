"""`iotad info` says where each joint of a motor node was when the recording ends: a robot whose
axes went to FAULT and stayed there (its controllers restarted) stops with no violation to say
so, and the line names the joints, since when, and the event that put them there."""
from iotad.cli import main
from iotad.node_host import wire
from iotad.recording.mcap_sink import McapSink


def status(joint, phase, event, lost=False):
    return {"joint": joint, "node_id": joint + 1, "event": event, "phase": phase, "lost": lost}


def test_a_joint_left_in_fault_is_named_with_when_and_why(tmp_path, capsys):
    out = tmp_path / "r.mcap"
    sink = McapSink(out)
    sink.add_metadata("iotad.recording", {"system": '"s"', "clock": '"virtual"', "time_unit": "1.0"})
    trace = sink.channel(wire.trace_key("s", "motor"), "iotad.trace_event", {})
    reports = [(1.0, 0, status(0, "ARMED", "ARMED")), (1.0, 1, status(1, "ARMED", "ARMED")),
               (2.0, 1, status(1, "FAULT", "DISARMED")),   # its controller came back IDLE
               (2.5, 0, status(0, "ARMED", "HEARTBEAT")), (2.5, 1, status(1, "FAULT", "HEARTBEAT"))]
    for seq, (t, joint, value) in enumerate(reports):
        e = {"t": t, "iota": "motor", "action": "joint_status", "index": joint, "kind": "output", "value": value}
        sink.write(trace, int(t * 1e9), int(t * 1e9), seq, wire.encode(e))
    sink.finish()
    assert main(["info", str(out)]) == 0
    said = capsys.readouterr().out
    assert "  joints at the end: motor: 1 of 2 joints ARMED; joint(s) 1 FAULT since t=2.000 s (DISARMED)" in said
