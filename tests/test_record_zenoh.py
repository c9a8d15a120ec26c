"""`iotad record` as a process on zenoh: publish times, sequence gaps, stored specs, a clean stop on
SIGINT, and a SIGKILLed recorder made whole by `iotad recover` with at most the last 100 ms lost."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from iotad import wire
from iotad.cli import main
from iotad.recording import read_recording
from iotad.transport import open_session
from launcher_helpers import free_port

ROOT = Path(__file__).resolve().parents[1]


def wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.01)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


class RecorderProcess:
    def __init__(self, tmp_path, keys, *extra):
        self.port = free_port()
        self.output = tmp_path / "rec.mcap"
        ready = tmp_path / "ready"
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "iotad.cli", "record", *keys, "-o", str(self.output),
             "--listen", f"tcp/127.0.0.1:{self.port}", "--ready-file", str(ready), "--quiet", *extra],
            cwd=ROOT, stderr=subprocess.PIPE, text=True)
        wait_for(lambda: ready.exists() or self.proc.poll() is not None, 20, "the recorder to subscribe")
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
    wait_for(lambda: publisher.matching_status.matching, 10, "the recorder's subscription to reach the publisher")


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
        wait_for(lambda: len(read_recording(recorder.output).messages) >= 6, 10, "the messages in the file")
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
