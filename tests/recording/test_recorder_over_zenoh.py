"""`iotad record` as a process on zenoh: publish times, sequence gaps, stored specs, a clean stop on
SIGINT, and a SIGKILLed recorder made whole by `iotad recover` with at most the last 100 ms lost."""
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from iotad.node_host import wire
from iotad.cli import main
from iotad.recording.mcap_reader import read_recording
from iotad.node_host.transport import open_session
from launcher_helpers import free_port
from node_harness import wait_for

ROOT = Path(__file__).resolve().parents[2]


class RecorderProcess:
    def __init__(self, tmp_path, keys, *extra, output=None, hub=None):
        """Listening on a port of its own, or with `hub` (an endpoint) connected to that hub."""
        self.port = free_port()
        self.output = output or tmp_path / "rec.mcap"
        ready = tmp_path / "ready"
        where = ["--connect", hub] if hub else ["--listen", f"tcp/127.0.0.1:{self.port}"]
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "iotad.cli", "record", *keys, "-o", str(self.output),
             *where, "--ready-file", str(ready), "--quiet", *extra],
            cwd=ROOT, stderr=subprocess.PIPE, text=True)
        wait_for(lambda: ready.exists() or self.proc.poll() is not None, 20, what="the recorder to subscribe")
        assert self.proc.poll() is None, self.proc.stderr.read()

    def stop(self, sig=signal.SIGINT):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        self.proc.wait(20)
        return self.proc.returncode


@pytest.fixture
def session_for():
    sessions = []

    def make(port):
        session = open_session(connect=[f"tcp/127.0.0.1:{port}"])
        sessions.append(session)
        return session

    yield make
    for session in sessions:
        session.close()


def matched(publisher):
    wait_for(lambda: publisher.matching_status.matching, 10, what="the recorder's subscription to reach the publisher")


def test_publish_time_gaps_spec_and_clean_stop(tmp_path, session_for):
    recorder = RecorderProcess(tmp_path, ["iota/t/**"])
    try:
        session = session_for(recorder.port)
        spec = {"path": "pub", "source": {"kind": "python", "ref": str(ROOT / "examples/scheduler.py") + ":Scheduler"},
                "text": None, "params": {"N": 2, "T": 0.5},
                "channels": [{"name": "ack", "direction": "output", "type": "ack", "type_name": "ack",
                              "schema": {"type": "string", "enum": ["COMMIT", "ABORT", "REJECT"], "title": "ack"}}]}
        queryable = session.declare_queryable("iota/t/pub/@spec",
                                              lambda q: q.reply("iota/t/pub/@spec", wire.encode(spec)))
        ack = session.declare_publisher("iota/t/pub/ack/0")
        trace = session.declare_publisher("iota/t/pub/@trace")
        matched(ack)
        matched(trace)
        sent = {}
        for seq in [0, 1, 2, 5, 6]:  # 3 and 4 never sent: a gap of two
            send_ns = time.time_ns()
            sent[seq] = send_ns
            ack.put(wire.encode("COMMIT"), attachment=wire.encode_attachment(seq, send_ns))
        trace.put(wire.encode({"t": 0.1, "iota": "pub", "action": "x", "index": None, "kind": "violation",
                               "value": {"violation": "bad_value", "message": "m"}}),
                  attachment=wire.encode_attachment(0))
        # the recorder flushes every 50 ms: read the growing file until all six are in it
        wait_for(lambda: len(read_recording(recorder.output).messages) >= 6, 10, what="the messages in the file")
    finally:
        assert recorder.stop() == 0
        queryable.undeclare()
    recording = read_recording(recorder.output)
    assert recording.complete
    messages = [m for m in recording.messages if m.topic == "iota/t/pub/ack/0"]
    assert [m.sequence for m in messages] == [0, 1, 2, 5, 6]
    assert [m.publish_time for m in messages] == [sent[s] for s in [0, 1, 2, 5, 6]]
    assert all(m.log_time >= m.publish_time for m in messages)
    assert recording.gaps() == [{"key": "iota/t/pub/ack/0", "expected": 3, "got": 5, "missing": 2}]
    assert recording.metadata["iotad.gaps"] == {"count": "1", "missing": "2"}
    assert recording.specs["pub"]["params"] == {"N": 2, "T": 0.5}
    assert recording.schema_of("iota/t/pub/ack/0").name == "ack"
    assert json.loads(recording.schema_of("iota/t/pub/ack/0").data)["enum"] == ["COMMIT", "ABORT", "REJECT"]
    assert len(recording.violations()) == 1


def test_sigkill_then_recover_loses_at_most_100ms(tmp_path, session_for, capsys):
    recorder = RecorderProcess(tmp_path, ["iota/k/**"])
    session = session_for(recorder.port)
    publisher = session.declare_publisher("iota/k/src/out", congestion_control=zenoh.CongestionControl.BLOCK)
    matched(publisher)
    sent: list[int] = []
    period = 1 / 2000  # 2000 messages a second
    start = time.monotonic()
    killed_ns = None
    while time.monotonic() - start < 1.5:
        if killed_ns is None and time.monotonic() - start >= 1.0:
            killed_ns = time.time_ns()
            os.kill(recorder.proc.pid, signal.SIGKILL)
        due = start + len(sent) * period
        if time.monotonic() < due:
            # sleep, not spin: a spinning sender takes a whole core from the recorder on a 2-core box
            time.sleep(min(0.001, max(0.0, due - time.monotonic())))
            continue
        send_ns = time.time_ns()
        publisher.put(wire.encode(len(sent)), attachment=wire.encode_attachment(len(sent), send_ns))
        sent.append(send_ns)
    recorder.stop()
    assert recorder.proc.returncode == -signal.SIGKILL
    with pytest.raises(Exception):
        from mcap.reader import make_reader
        with open(recorder.output, "rb") as stream:
            make_reader(stream).get_summary()  # no footer: the seeking reader cannot open it
    recovered = tmp_path / "recovered.mcap"
    assert main(["recover", str(recorder.output), "-o", str(recovered)]) == 0
    assert "was cut short" in capsys.readouterr().out
    recording = read_recording(recovered)
    assert recording.complete
    got = {m.sequence for m in recording.messages if m.topic == "iota/k/src/out"}
    before_kill = [seq for seq, ns in enumerate(sent) if ns < killed_ns]
    must_have = [seq for seq, ns in enumerate(sent) if ns < killed_ns - 100_000_000]
    missing = [seq for seq in must_have if seq not in got]
    lost = [seq for seq in before_kill if seq not in got]
    window = (killed_ns - sent[lost[0]]) / 1e6 if lost else 0.0
    recorded = sorted((m for m in recording.messages if m.topic == "iota/k/src/out"), key=lambda m: m.log_time)
    last = recorded[-1]
    print(f"published {len(before_kill)} before the kill, recovered {len(got)}; "
          f"lost {len(lost)}, all from the last {window:.1f} ms; the recorder's last flushed message "
          f"arrived {(killed_ns - last.log_time) / 1e6:.1f} ms before the kill, "
          f"{(last.log_time - last.publish_time) / 1e6:.1f} ms after it was sent")
    assert len(must_have) > 1500
    assert not missing, f"{len(missing)} messages older than 100 ms before the kill were lost: {missing[:5]}..."
    assert got <= set(before_kill)


# ------------------------------------------------------------------ trace-sourced (iotad run's mode)
def output_event(key, seq, send_ns, value, iota="pub"):
    channel = key.split("/")[3]
    return {"t": 0.1 * seq, "iota": iota, "action": channel, "index": None, "kind": "output", "value": value,
            "key": key, "seq": seq, "send_ns": send_ns}


def test_trace_sourced_messages_gaps_and_injected_inputs(tmp_path, session_for):
    recorder = RecorderProcess(tmp_path, ["iota/t/**"], "--from-traces")
    try:
        session = session_for(recorder.port)
        trace = session.declare_publisher("iota/t/pub/@trace")
        other = session.declare_publisher("iota/t/src/@trace")
        matched(trace)
        matched(other)
        sent, trace_seq = {}, 0
        for seq in [0, 1, 2, 5, 6]:  # 3 and 4 never sent: a gap of two on the output key
            sent[seq] = time.time_ns() - 1000
            trace.put(wire.encode(output_event("iota/t/pub/ack/0", seq, sent[seq], "COMMIT")),
                      attachment=wire.encode_attachment(trace_seq))
            trace_seq += 1
        # src's output, received by pub: recorded once, from src's trace
        other.put(wire.encode(output_event("iota/t/src/out", 0, 111, 3, iota="src")), attachment=wire.encode_attachment(0))
        received = {"t": 1.0, "iota": "pub", "action": "inp", "index": None, "kind": "input", "value": 3,
                    "key": "iota/t/src/out", "seq": 0, "send_ns": 111}
        injected = dict(received, key="iota/t/pub/inp", seq=4, send_ns=222, value=9)  # `iotad pub` into pub
        trace_seq += 1  # one @trace event lost on the way: a gap on the trace stream
        for event in (received, injected):
            trace.put(wire.encode(event), attachment=wire.encode_attachment(trace_seq))
            trace_seq += 1
        wait_for(lambda: len(read_recording(recorder.output).messages) >= 8 + 7, 10, what="the messages in the file")
    finally:
        assert recorder.stop() == 0
    recording = read_recording(recorder.output)
    assert recording.info["source"] == "traces"
    assert "iota/t/**" not in recording.info["keys"]  # no channel key subscribed: no wake-up per message
    acks = [m for m in recording.messages if m.topic == "iota/t/pub/ack/0"]
    assert [(m.sequence, m.publish_time, m.value) for m in acks] == [(s, sent[s], "COMMIT") for s in [0, 1, 2, 5, 6]]
    assert all(m.log_time >= m.publish_time for m in acks)
    assert [(m.sequence, m.publish_time, m.value) for m in recording.messages if m.topic == "iota/t/src/out"] == [(0, 111, 3)]
    assert [(m.sequence, m.publish_time, m.value) for m in recording.messages if m.topic == "iota/t/pub/inp"] == [(4, 222, 9)]
    assert recording.gaps() == [{"key": "iota/t/pub/ack/0", "expected": 3, "got": 5, "missing": 2},
                                {"key": "iota/t/pub/@trace", "expected": 5, "got": 6, "missing": 1}]
    assert len(recording.trace("pub")) == 7


@contextlib.contextmanager
def echo_recorded(tmp_path, session_for):
    """An Echo node on a trace-sourced recorder's port, running (its first heartbeat seen):
    yields (recorder, session); stops both on the way out."""
    recorder = RecorderProcess(tmp_path, ["iota/t/**"], "--from-traces")
    config = {"system": "t", "path": "echo", "source": {"kind": "python", "ref": str(ROOT / "examples/echo.py") + ":Echo"},
              "listen": ["tcp/127.0.0.1:0"], "connect": [f"tcp/127.0.0.1:{recorder.port}"], "heartbeat_period": 0.2}
    node = subprocess.Popen([sys.executable, "-m", "iotad.node_host", "--config-json", json.dumps(config)], cwd=ROOT)
    try:
        session = session_for(recorder.port)
        beats = session.declare_subscriber("iota/t/echo/@heartbeat", zenoh.handlers.FifoChannel(16))
        beats.handler.recv()  # the node runs
        yield recorder, session
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(20)
        assert recorder.stop() == 0


def test_trace_sourced_records_a_node_and_iotad_pub_into_its_input(tmp_path, session_for):
    from iotad.recording.replay import replay_node

    with echo_recorded(tmp_path, session_for) as (recorder, _):
        assert main(["pub", "iota/t/echo/inp", "7", "--count", "3", "--rate", "50", "--wait", "10",
                     "--connect", f"tcp/127.0.0.1:{recorder.port}"]) == 0
        wait_for(lambda: sum(m.topic == "iota/t/echo/out" for m in read_recording(recorder.output).messages) >= 3,
                 10, what="the echo's answers in the file")
    recording = read_recording(recorder.output)
    inputs = [e for e in recording.trace("echo") if e["kind"] == "input"]
    injected = [m for m in recording.messages if m.topic == "iota/t/echo/inp"]
    assert [(m.value, m.sequence, m.publish_time) for m in injected] == [(7, e["seq"], e["send_ns"]) for e in inputs]
    assert [m.sequence for m in injected] == [0, 1, 2]
    answers = [m for m in recording.messages if m.topic == "iota/t/echo/out"]
    assert [(m.value, m.sequence) for m in answers] == [(7, 0), (7, 1), (7, 2)]
    assert all(m.log_time >= m.publish_time > 0 for m in answers + injected)
    assert recording.schema_of("iota/t/echo/out").name != "any"
    assert replay_node(recording, "echo").ok


def test_trace_sourced_an_input_the_node_refused_is_no_gap(tmp_path, session_for):
    """A publisher outside the system sends 7, -1 (out of range: refused), 7: the refusal is a
    recorded violation that names the message's key and sequence number, so the recorder counts
    #1 as seen; before, the third message made a gap of one that never was."""
    with echo_recorded(tmp_path, session_for) as (recorder, session):
        publisher = session.declare_publisher("iota/t/echo/inp")
        matched(publisher)
        for seq, value in enumerate([7, -1, 7]):
            publisher.put(wire.encode(value), attachment=wire.encode_attachment(seq, time.time_ns()))
            time.sleep(0.05)
        wait_for(lambda: sum(m.topic == "iota/t/echo/out" for m in read_recording(recorder.output).messages) >= 2,
                 10, what="the echo's answers in the file")
    recording = read_recording(recorder.output)
    refused = [e for e in recording.trace("echo") if e["kind"] == "violation"]
    assert len(refused) == 1 and refused[0]["value"]["violation"] == "bad_value"
    assert (refused[0]["key"], refused[0]["seq"]) == ("iota/t/echo/inp", 1)
    assert [m.sequence for m in recording.messages if m.topic == "iota/t/echo/inp"] == [0, 2]
    assert recording.gaps() == []


def test_trace_sourced_sigkill_loses_at_most_100ms_of_what_arrived(tmp_path, session_for, capsys):
    """Trace bursts every 20 ms (as a node host sends them), 2000 output events a second: after a
    SIGKILL, every event that reached the recorder more than 100 ms before the kill is on its key."""
    recorder = RecorderProcess(tmp_path, ["iota/k/**"], "--from-traces")
    session = session_for(recorder.port)
    trace = session.declare_publisher("iota/k/src/@trace", congestion_control=zenoh.CongestionControl.BLOCK,
                                      priority=zenoh.Priority.DATA_LOW)
    matched(trace)
    put_ns: list[int] = []  # when each event left in its burst
    start = time.monotonic()
    killed_ns = None
    while time.monotonic() - start < 1.5:
        if killed_ns is None and time.monotonic() - start >= 1.0:
            killed_ns = time.time_ns()
            os.kill(recorder.proc.pid, signal.SIGKILL)
        time.sleep(0.02)
        due = int((time.monotonic() - start) * 2000)
        first, now = len(put_ns), time.time_ns()
        burst = [output_event("iota/k/src/out", seq, now, seq, iota="src") for seq in range(first, due)]
        if burst:  # one sample per burst, as a node host sends its trace
            trace.put(wire.encode_burst(burst), attachment=wire.encode_attachment(first, now))
            put_ns += [now] * len(burst)
    recorder.stop()
    assert recorder.proc.returncode == -signal.SIGKILL
    recovered = tmp_path / "recovered.mcap"
    assert main(["recover", str(recorder.output), "-o", str(recovered)]) == 0
    recording = read_recording(recovered)
    got = {m.sequence for m in recording.messages if m.topic == "iota/k/src/out"}
    assert got == {e["seq"] for e in recording.trace("src")}  # each output with its trace event
    before_kill = [seq for seq, ns in enumerate(put_ns) if ns < killed_ns]
    must_have = [seq for seq, ns in enumerate(put_ns) if ns < killed_ns - 100_000_000]
    missing = [seq for seq in must_have if seq not in got]
    lost = [seq for seq in before_kill if seq not in got]
    window = (killed_ns - put_ns[lost[0]]) / 1e6 if lost else 0.0
    print(f"sent {len(before_kill)} events before the kill, recovered {len(got)}; lost {len(lost)}, "
          f"all from the last {window:.1f} ms")
    assert len(must_have) > 1500
    assert not missing, f"{len(missing)} events older than 100 ms before the kill were lost: {missing[:5]}..."


def test_trace_bursts_are_split_into_events_and_malformed_ones_are_recorded(tmp_path, session_for):
    """A @trace sample is a burst (list of events) or one event (dict, the old form): each event
    is one message on the @trace channel, numbered from the burst's seq; a gap on the @trace
    stream counts events; an undecodable burst, a payload that is no burst, and an element that
    is no event are recorded on @recorder/malformed, and the rest of the stream is recorded."""
    recorder = RecorderProcess(tmp_path, ["iota/t/**"], "--from-traces")
    try:
        session = session_for(recorder.port)
        trace = session.declare_publisher("iota/t/pub/@trace")
        matched(trace)
        start = wire.start_event(0.0, "pub", 1.0, 1)
        burst = [start] + [output_event("iota/t/pub/ack/0", seq, 100 + seq, "COMMIT") for seq in range(3)]
        trace.put(wire.encode_burst(burst), attachment=wire.encode_attachment(0, 50))       # seq 0..3
        trace.put(wire.encode(output_event("iota/t/pub/ack/0", 3, 103, "ABORT")),           # seq 4, old form
                  attachment=wire.encode_attachment(4, 51))
        # seq 5 and 6 lost on the way: a gap of two events on the trace stream
        trace.put(wire.encode_burst([output_event("iota/t/pub/ack/0", 4, 104, "COMMIT"), 17,
                                     output_event("iota/t/pub/ack/0", 5, 105, "COMMIT")]),
                  attachment=wire.encode_attachment(7, 52))                                  # seq 7..9
        trace.put(b"\xc1\xc1", attachment=wire.encode_attachment(10, 53))                  # undecodable
        trace.put(wire.encode("no burst"), attachment=wire.encode_attachment(11, 54))       # neither
        trace.put(wire.encode_burst([output_event("iota/t/pub/ack/0", 6, 106, "COMMIT")]),
                  attachment=wire.encode_attachment(40, 55))  # after what could not be counted: no gap
        wait_for(lambda: len(read_recording(recorder.output).malformed()) >= 3
                 and sum(m.topic == "iota/t/pub/ack/0" for m in read_recording(recorder.output).messages) >= 7,
                 10, what="the messages in the file")
    finally:
        assert recorder.stop() == 0
    recording = read_recording(recorder.output)
    traced = [m for m in recording.messages if m.topic == "iota/t/pub/@trace"]
    assert [(m.sequence, m.publish_time) for m in traced] == [(0, 50), (1, 50), (2, 50), (3, 50), (4, 51),
                                                              (7, 52), (9, 52), (40, 55)]
    assert all(isinstance(m.value, dict) for m in traced)  # one event a message: the format is unchanged
    assert recording.start_times() == {"pub": 0.0}
    assert [e["kind"] for e in recording.trace("pub", starts=True)] == ["start"] + ["output"] * 7
    acks = [(m.sequence, m.publish_time, m.value) for m in recording.messages if m.topic == "iota/t/pub/ack/0"]
    assert acks == [(0, 100, "COMMIT"), (1, 101, "COMMIT"), (2, 102, "COMMIT"), (3, 103, "ABORT"),
                    (4, 104, "COMMIT"), (5, 105, "COMMIT"), (6, 106, "COMMIT")]
    assert recording.gaps() == [{"key": "iota/t/pub/@trace", "expected": 5, "got": 7, "missing": 2}]
    malformed = recording.malformed()
    assert [(p["key"], p["seq"]) for p in malformed] == [("iota/t/pub/@trace", 8), ("iota/t/pub/@trace", 10),
                                                         ("iota/t/pub/@trace", 11)]
    assert "element 1" in malformed[0]["message"] and malformed[0]["data"] == wire.encode(17)
    assert "undecodable" in malformed[1]["message"] and malformed[1]["data"] == b"\xc1\xc1"
    assert "neither" in malformed[2]["message"]
    assert recording.metadata["iotad.stats"]["malformed"] == "3"


def test_a_recorder_on_a_hub_gets_the_first_sample_of_every_new_node(tmp_path):
    """A node that has just joined the hub publishes its start record at once. The recorder, a
    client of the hub, gets it through the hub; as a peer it waited for gossip to link it to
    the node, and a node's first sample was lost about one time in seven."""
    port = free_port()
    hub = open_session([f"tcp/127.0.0.1:{port}"])
    other = open_session(connect=[f"tcp/127.0.0.1:{port}"])  # a node already running
    recorder = RecorderProcess(tmp_path, ["iota/t/**"], hub=f"tcp/127.0.0.1:{port}")
    sent = []
    try:
        for n in range(12):
            with open_session(connect=[f"tcp/127.0.0.1:{port}"]) as node:
                key = f"iota/t/n{n}/@trace"
                node.declare_publisher(key).put(wire.encode(wire.start_event(0.0, f"n{n}", 1.0, n)),
                                               attachment=wire.encode_attachment(0))
                sent.append(key)
                time.sleep(0.05)  # zenoh sends before the session closes
        wait_for(lambda: len(read_recording(recorder.output).messages) >= len(sent), 10,
                 what="every node's first sample in the file")
    finally:
        assert recorder.stop() == 0
        other.close()
        hub.close()
    assert sorted(m.topic for m in read_recording(recorder.output).messages) == sorted(sent)


def record_without_a_hub(tmp_path, *extra):
    """`iotad record` connecting to a port where no hub listens yet, once it says it waits."""
    port, err = free_port(), tmp_path / "record.err"
    with open(err, "w") as sink:
        proc = subprocess.Popen([sys.executable, "-m", "iotad.cli", "record", "iota/t/**", "-o", str(tmp_path / "r.mcap"),
                                 "--connect", f"tcp/127.0.0.1:{port}", *extra], cwd=ROOT, stderr=sink, text=True)
    wait_for(lambda: "waiting for a hub" in err.read_text() or proc.poll() is not None, 20, what="the recorder to wait")
    assert proc.poll() is None, err.read_text()
    assert err.read_text().startswith(f"waiting for a hub at tcp/127.0.0.1:{port} (Ctrl-C to stop)")
    return proc, port, err


def test_a_recorder_started_before_its_hub_waits_for_it(tmp_path):
    ready, output = tmp_path / "ready", tmp_path / "r.mcap"
    proc, port, err = record_without_a_hub(tmp_path, "--ready-file", str(ready))
    try:
        assert not ready.exists()
        with open_session([f"tcp/127.0.0.1:{port}"]) as hub:
            wait_for(ready.exists, 20, what="the recorder to join the hub")
            publisher = hub.declare_publisher("iota/t/a/x/0")
            matched(publisher)
            publisher.put(wire.encode(1), attachment=wire.encode_attachment(0))
            wait_for(lambda: len(read_recording(output).messages) == 1, 10, what="the sample in the file")
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(20)
    assert proc.returncode == 0, err.read_text()
    assert [m.topic for m in read_recording(output).messages] == ["iota/t/a/x/0"]


def test_ctrl_c_while_waiting_for_a_hub_is_a_clear_stop(tmp_path):
    proc, port, err = record_without_a_hub(tmp_path)
    try:
        proc.send_signal(signal.SIGINT)
        proc.wait(20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 2, err.read_text()
    assert f"stopped while waiting for a hub at tcp/127.0.0.1:{port}: nothing recorded, no file written" \
        in err.read_text()
    assert "Traceback" not in err.read_text()
    assert not (tmp_path / "r.mcap").exists()  # no empty recording to make the next run ask for --force


def test_duration_counts_while_waiting_for_a_hub(tmp_path):
    proc, port, err = record_without_a_hub(tmp_path, "--duration", "2")
    try:
        proc.wait(20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 2, err.read_text()
    assert f"--duration 2 s over while waiting for a hub at tcp/127.0.0.1:{port}: nothing recorded" in err.read_text()
    assert not (tmp_path / "r.mcap").exists()


def test_missing_folders_of_the_output_are_created(tmp_path):
    output = tmp_path / "new" / "deeper" / "rec.mcap"
    recorder = RecorderProcess(tmp_path, ["iota/t/**"], output=output)
    assert recorder.stop() == 0
    assert read_recording(output).complete


def test_given_a_system_file_and_no_connect_the_recorder_goes_to_its_hub(tmp_path):
    from iotad.cli.commands.record import _hub_of
    system = tmp_path / "s.toml"
    system.write_text('[system]\nname = "s"\n[system.endpoints]\nlisten = ["tcp/127.0.0.1:7600", "tcp/127.0.0.1:7601"]\n')
    assert _hub_of(str(system)) == ["tcp/127.0.0.1:7600", "tcp/127.0.0.1:7601"]
    system.write_text('[system]\nname = "s"\n')
    assert _hub_of(str(system)) == ["tcp/127.0.0.1:7447"]  # where `iotad run` puts it by default
    assert _hub_of(None) == []  # no system file, no --connect: listen only, as before


def test_a_rogue_publisher_cannot_make_a_recording_unreadable(tmp_path, session_for, capsys):
    """What a rogue or broken publisher puts on `@trace` (a map that is no trace event), on
    `@launcher` or on `@heartbeat` (no msgpack map) is recorded on @recorder/malformed, not on
    its key, where every reader would take it for an event: the file stays readable whole."""
    recorder = RecorderProcess(tmp_path, ["iota/t/**", "iota/t/**/@trace", "iota/t/@launcher",
                                          "iota/t/**/@heartbeat"])
    try:
        session = session_for(recorder.port)
        trace = session.declare_publisher("iota/t/pub/@trace")
        launcher = session.declare_publisher("iota/t/@launcher")
        beat = session.declare_publisher("iota/t/pub/@heartbeat")
        matched(trace)
        good = {"t": 1.0, "iota": "pub", "action": "out", "index": None, "kind": "internal", "value": None}
        trace.put(wire.encode_burst([dict(good, t="x"), {"kind": "output"}, good]),
                  attachment=wire.encode_attachment(0, 50))
        launcher.put(b"\xc1", attachment=wire.encode_attachment(0, 60))
        launcher.put(wire.encode([1, 2]), attachment=wire.encode_attachment(1, 61))
        launcher.put(wire.encode({"event": "live", "node": "pub", "t_ns": 5}), attachment=wire.encode_attachment(2, 62))
        beat.put(b"\xc1", attachment=wire.encode_attachment(0, 70))
        wait_for(lambda: len(read_recording(recorder.output).malformed()) >= 5
                 and read_recording(recorder.output).launcher_events(), 10, what="the messages in the file")
    finally:
        assert recorder.stop() == 0
    recording = read_recording(recorder.output)
    assert [e["t"] for e in recording.trace("pub")] == [1.0]  # the good event, read without a fault
    assert [e["event"] for e in recording.launcher_events()] == ["live"]
    problems = sorted((p["key"], p["message"].split(":")[0]) for p in recording.malformed())
    assert problems == sorted([("iota/t/pub/@trace", "element 0 of the burst is no trace event"),
                        ("iota/t/pub/@trace", "element 1 of the burst is no trace event"),
                        ("iota/t/@launcher", "undecodable msgpack (1 bytes)"),
                        ("iota/t/@launcher", "a list, not a map"),
                        ("iota/t/pub/@heartbeat", "undecodable msgpack (1 bytes)")])
    capsys.readouterr()
    assert main(["info", str(recorder.output)]) == 0
    assert "Traceback" not in capsys.readouterr().err
