"""A node that its host's launcher restarted while the host was cut off from the hub: the hub's
recorder heard neither the new process's start record nor its first events, and the new process
numbers its trace from 0 again, so that its sequence numbers may even run on from the old one's
with no jump. Every `@trace` burst names the process that sent it (pid and start stamp, in its
attachment); the recorder notes a new process whose start it did not hear, and `iotad check` and
`iotad replay` of the hub's file alone judge the old process up to its last event heard and the
new one as a run of its own: never the new process's events against the old one's state, and the
restart is said.

- A real node host's bursts name its process (its start record's pid and wall time).
- A real recorder (`iotad record`) given the bursts of two processes of one node, the second heard
  from its fifth event on, notes the new process (`wire.restart_note`), and none for a process
  heard from its start nor for the bursts that follow.
- The hub's file with that note (built by hand as the recorder writes it, from a virtual run of a
  pulse, as tests/recording/test_checking_one_hosts_file_after_a_cut_judges_up_to_the_gap_and_says_so.py
  builds one) is checked and replayed from the hub's file alone."""
import signal
import subprocess
import sys
import threading

import msgpack
import pytest

from iotad.cli import main
from iotad.kernel.compose import Composite
from iotad.node_host import wire
from iotad.node_host.transport import free_port, open_session
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import FORMAT, GAP_TOPIC, packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from namespaces import hosts_header
from node_harness import ROOT, Hub, Node, node_config, wait_for
from system_iotas import Pulse

ORIGIN = 1_700_000_000.0
SYSTEM = hosts_header("long", "10.0.0.1", 7447, "brain", "arm", "10.0.0.2") + f"""

[[node]]
name = "tick"
host = "brain"
python = "{ROOT / 'tests' / 'system_iotas.py'}:Pulse"
params = {{ period = 0.5 }}
[[node]]
name = "beat"
host = "arm"
python = "{ROOT / 'tests' / 'system_iotas.py'}:Pulse"
params = {{ period = 0.5 }}
"""
CUT = (3.0, 7.0)  # arm's events inside it never reached the hub's recorder
KILLED, RESTARTED = 5.2, 5.5  # beat's first process killed, the second's engine started (arm's launcher)
LOST, BACK = 6.0, 8.0  # the hub's launcher: host arm lost, then back (its nodes ran on)
OLD_PID, NEW_PID = 101, 202


def ns(t: float) -> int:
    return round((ORIGIN + t) * 1e9)


def test_a_node_hosts_trace_bursts_name_its_process():
    hub = Hub()
    attachments = []
    hub.session.declare_subscriber(
        "iota/test/pulse/@trace",
        lambda s: attachments.append((msgpack.unpackb(s.attachment.to_bytes()), wire.decode(s.payload.to_bytes()))))
    node = Node(node_config(hub, "pulse", f"{ROOT / 'tests' / 'system_iotas.py'}:Pulse", params={"period": 0.05}))
    try:
        wait_for(lambda: len(attachments) >= 3, 20, what="three trace bursts of the node")
    finally:
        node.stop()
        hub.close()
    start = attachments[0][1][0]
    assert start["kind"] == wire.START_KIND and start["value"]["pid"] == node.process.pid
    for fields, _ in attachments:
        # [seq, send_ns, pid, started_ns]: every burst names the process and its start, exactly
        assert len(fields) == 4, fields
        pid, started_ns = fields[2:]
        assert wire.trace_process(fields) == (pid, started_ns)
        assert pid == node.process.pid and started_ns / 1e9 == pytest.approx(start["value"]["wall"], abs=1e-6), fields
        assert wire.decode_attachment(msgpack.packb(fields))[0] == fields[0]


def burst(events, seq, process):
    """A `@trace` sample as a node host sends it: `[seq, send_ns, pid, started_ns]` attached."""
    return wire.encode_burst(events), msgpack.packb([seq, ns(events[0]["t"]), *process])


def note(key, after, got, process):
    """The recorder's note of a new process whose first `got` events it did not hear."""
    return {"key": key, "expected": 0, "got": got, "missing": got, "after": after,
            "process": {"pid": process[0], "started_ns": process[1]}}


def test_the_recorder_notes_a_new_process_whose_start_it_did_not_hear(tmp_path):
    port, ready, output = free_port(), tmp_path / "ready", tmp_path / "rec.mcap"
    recorder = subprocess.Popen([sys.executable, "-m", "iotad.cli", "record", "iota/long/**", "-o", str(output),
                                 "--listen", f"tcp/127.0.0.1:{port}", "--ready-file", str(ready), "--quiet"],
                                cwd=ROOT, stderr=subprocess.PIPE, text=True)
    session = None
    try:
        wait_for(lambda: ready.exists() or recorder.poll() is not None, 20, what="the recorder to subscribe")
        assert recorder.poll() is None, recorder.stderr.read()
        session = open_session([], [f"tcp/127.0.0.1:{port}"], mode="client")
        trace = session.declare_publisher(wire.trace_key("long", "beat"))
        wait_for(lambda: trace.matching_status.matching, 10, what="the recorder's subscription")
        key = wire.trace_key("long", "beat")

        def out(t, n):
            return {"t": t, "iota": "beat", "action": "out", "index": None, "kind": "output", "value": n}

        first, second, third = (OLD_PID, ns(0)), (NEW_PID, ns(RESTARTED)), (303, ns(10))
        sent = [
            burst([wire.start_event(0.0, "beat", ORIGIN, OLD_PID), out(0.5, 0)], 0, first),
            burst([out(1.0, 1), out(1.5, 2)], 2, first),
            burst([out(2.0, 3)], 4, first),
            # (seq 5..: the first process's last events, then the second's start record and its
            # first 4 events: never heard) the second, from its seq 5: no jump from the first's
            burst([out(7.5, 4)], 5, second),
            burst([out(8.0, 5)], 6, second),
            # a third process heard from its start: its start record says it, no note
            burst([wire.start_event(10.0, "beat", ORIGIN + 10.0, 303), out(10.5, 0)], 0, third),
        ]
        for payload, attachment in sent:
            trace.put(payload, attachment=attachment)

        def written() -> int:
            try:
                recording = read_recording(output, salvage=True)
            except Exception:  # noqa: BLE001 - nothing flushed yet
                return 0
            return sum(1 for m in recording.messages if m.topic == key)

        wait_for(lambda: written() == 9, 20, what="every event sent to be written")
    finally:
        if session is not None:
            session.close()
        recorder.send_signal(signal.SIGINT)
        recorder.wait(20)
    recording = read_recording(output)
    notes = [m.value for m in recording.messages if m.topic == GAP_TOPIC]
    # before: no note at all (the attachment of four was not even read: every seq taken for 0)
    assert notes == [note(key, 5, 5, (NEW_PID, ns(RESTARTED)))], notes
    assert notes == [wire.restart_note(key, 5, 5, (NEW_PID, ns(RESTARTED)))]
    events = recording.process_trace("beat")
    starts = [(e["t"], e["value"]["pid"], e["value"].get("from")) for e in events if e["kind"] == wire.START_KIND]
    assert starts == [(0.0, OLD_PID, None), (pytest.approx(RESTARTED), NEW_PID, "recorder"), (10.0, 303, None)]
    # the second process's first event heard carries the gap: its 5 first events were not heard
    marked = [(e["t"], e["missed"]["missing"]) for e in events if e.get("missed")]
    assert marked == [(7.5, 5)], marked


def hubs_file(tmp_path, noted: bool = True, host: str = "brain"):
    """The hub's recording of 12 s (a virtual run's events as node hosts publish them, received 1 ms
    after): tick on brain heard whole; beat on arm heard up to the cut, its first process killed
    at KILLED, the second started at RESTARTED by arm's launcher, heard from the cut's end on,
    with the recorder's note of the new process (`noted`), and the hub's launcher's `down` and
    `host_back` of arm. `host="arm"`: arm's own recording of the same run, every event of beat's
    two processes (and the launchers' events), its clock the hub's."""
    virtual = tmp_path / "virtual.mcap"
    record_run(Composite("long", Pulse("tick", period=0.5), Pulse("beat", period=0.5)), virtual, until=12)
    ran = read_recording(virtual)
    messages = []  # (topic, log ns, publish ns, sequence, value)
    outputs = {node: [m.value for m in ran.messages if m.topic == wire.trace_key("long", node)]
               for node in ("tick", "beat")}
    processes = {"tick": [(0.0, 50, outputs["tick"])],
                 # the second process of beat: the pulse from its own start, RESTARTED s later
                 "beat": [(0.0, OLD_PID, [e for e in outputs["beat"] if e["t"] < KILLED]),
                          (RESTARTED, NEW_PID, [dict(e, t=e["t"] + RESTARTED) for e in outputs["beat"]
                                                if e["t"] + RESTARTED <= 12])]}
    if host == "arm":
        del processes["tick"]  # the hub's recording has brain's nodes
    for node, runs in processes.items():
        trace = wire.trace_key("long", node)
        expected = 0  # the seq the recorder expects next
        for started, pid, events in runs:
            heard = None
            for seq, event in enumerate([wire.start_event(started, node, ORIGIN + started, pid), *events]):
                if event["kind"] == "output":
                    event = dict(event, key=wire.channel_key("long", node, "out"), seq=event["value"],
                                 send_ns=ns(event["t"]))
                if host == "brain" and node == "beat" and CUT[0] < event["t"] < CUT[1]:
                    heard = False  # sent into the closed links: the hub's recorder never got it
                    continue
                received = ns(event["t"]) + 1_000_000
                if heard is False and pid == NEW_PID and noted:
                    messages.append((GAP_TOPIC, received, received, 0,
                                     note(trace, expected, seq, (pid, ns(started)))))
                heard, expected = True, seq + 1
                messages.append((trace, received, ns(event["t"]), seq, event))
                if event["kind"] == "output":
                    messages.append((event["key"], received, event["send_ns"], event["seq"], event["value"]))
    launcher = wire.launcher_key("long")
    messages.append((launcher, ns(LOST), ns(LOST), 0, {"event": "down", "node": "beat", "host": "arm", "pid": None,
                                                       "code": None, "t_ns": ns(LOST), "message": "host arm lost"}))
    messages.append((launcher, ns(BACK), ns(BACK), 1,
                     {"event": "host_back", "node": None, "host": "arm", "pid": 1, "code": None, "t_ns": ns(BACK),
                      "message": "host arm: back; its nodes ran on while it was cut off (beat)", "resumed": True}))
    path = tmp_path / ("long.mcap" if host == "brain" else f"long.{host}.mcap")
    sink = McapSink(path)
    run = {"host": host, "hub": host == "brain", "origin": ORIGIN}
    if host != "brain":
        run["clock"] = {"offset": 0.0, "bound": 0.0002, "samples": 16, "measured_ns": ns(-1)}
    sink.add_metadata("iotad.recording", {"format": FORMAT, "system": "long", "clock": "real", "source": "traces",
                                          "writer": "iotad run", "time_unit": 1.0, "run": run})
    sink.attach("system.toml", "application/toml", SYSTEM.encode())
    for node, spec in ran.specs.items():
        sink.add_spec(node, dict(spec, origin=ORIGIN), ns(0))
    for topic, log_ns, publish_ns, sequence, value in sorted(messages, key=lambda m: m[1]):
        sink.write(sink.channel(topic, "t", {}), log_ns, publish_ns, sequence, packb(value))
    sink.finish()
    return path


@pytest.fixture(scope="module")
def hub_file(tmp_path_factory):
    return hubs_file(tmp_path_factory.mktemp("restart"))


def test_the_hubs_file_alone_judges_the_new_process_as_a_new_run_and_says_it_restarted(hub_file, capsys):
    code = main(["check", str(hub_file), "--all", "--no-delivery"])
    out = capsys.readouterr().out
    lines = out.splitlines()
    # the second process's outputs (n=2 at t=7, its 3rd) never judged against the first's state
    # (n=6 after its 6 outputs heard): before, `wrong_value` at t=7 and after
    assert "[wrong_value]" not in out and "[late]" not in out and "[expired]" not in out, out
    beat = next(line for line in lines if line.startswith("beat: "))
    # judged: the first process's 6 outputs heard (t=0.5..3); the second's 11 (t=7..12) follow
    # events of it that were not heard (its start, its outputs at t=6 and 6.5): not judged
    assert beat == ("beat: 6 events, 6 firings checked, 0 problem(s); JUDGED ONLY UP TO A GAP in its trace "
                    "(11 event(s) after it not judged)"), out
    assert ("  GAP t=3..7: 3 event(s) of its trace are not in this recording (its process was restarted "
            "unheard: pid 202 started at t=5.5, and its start and first events were not heard; host arm lost: "
            "its nodes down at t=6, back at t=8); the 11 event(s) recorded after the gap (this run of its "
            "process) are not judged, since the state of its spec after the missing events is unknown") in lines, out
    assert "  restarted at t=5.5: each run of its process is checked from its own start" in lines, out
    assert "tick: 24 events, 24 firings checked, 0 problem(s)" in lines, out
    assert code == 1 and lines[-1].startswith("check: PROBLEMS FOUND (beat judged only up to a gap"), out


def test_replay_of_the_hubs_file_replays_the_first_process_and_says_the_restart(hub_file, capsys):
    code = main(["replay", str(hub_file), "--node", "beat"])
    out = capsys.readouterr().out
    # before: "replay diverges at output event #6: the replay never produced output out=2 at t=7"
    assert code == 0, out
    assert out.splitlines()[0].startswith("beat: replay agrees: 6 output events"), out
    assert "its process was restarted unheard: pid 202 started at t=5.5" in out, out


def test_the_merge_with_arms_own_file_judges_both_processes_whole(hub_file, tmp_path, capsys):
    """arm's own recording holds the new process's start and first events: in the merge the note
    is filled (its start record is there), and both processes are judged whole, no gap said."""
    from iotad.recording.merge import merge, write_merged

    merged = tmp_path / "merged.mcap"
    write_merged(merge([hub_file, hubs_file(tmp_path, host="arm")]), merged)
    assert not [m for m in read_recording(merged).messages if m.topic == GAP_TOPIC], "the note is filled"
    code = main(["check", str(merged), "--all", "--no-delivery"])
    out = capsys.readouterr().out
    lines = out.splitlines()
    # 10 outputs of the first process (t=0.5..5) and 13 of the second (t=6..12)
    assert "beat: 23 events, 23 firings checked, 0 problem(s)" in lines, out
    assert "  restarted at t=5.5: each run of its process is checked from its own start" in lines, out
    assert "GAP" not in out and code == 0, out


def test_info_names_the_new_process_among_the_sequence_gaps(hub_file, capsys):
    assert main(["info", str(hub_file)]) == 0
    out = capsys.readouterr().out
    assert ("    iota/long/beat/@trace: a new process (pid 202) first heard at #3, its start and first 3 event(s) "
            "not; the one before would have sent #7 next") in out.splitlines(), out
