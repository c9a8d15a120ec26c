"""kill -9 of the node that runs the scheduler's program (the MDL interpreter's place) while the
resume scheduler's master signals: the launcher restarts it, which starts empty; the scheduler
learns of it through the reader's liveliness (its `peer_restart` input names mdl_command, the
channel the reader is bound to) and sends the master's program again, and the master still
commits when its epoch is over. Real processes under `iotad run`; the kill is triggered by the
reader's own trace; every assertion is read from the recording."""
import os
import signal
import threading
from pathlib import Path

from iotad.node_host import wire
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import ROOT, Observer, children_of, free_port, launcher

EPOCH = 6.0
SETPOINT = 0.7


def system_file(tmp_path: Path, port: int) -> Path:
    path = tmp_path / "reader.toml"
    path.write_text(f"""
[system]
name = "reader"
time_unit = 1.0
external = ["scheduler.priority[0]"]
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]
[[node]]
name = "scheduler"
spec = "{ROOT / 'nodes/scheduler/resume.iota'}"
params = {{ N = 1, T = 0.5 }}
[[node]]
name = "reader"
python = "{ROOT / 'tests/system_iotas.py'}:CommandReader"
restart = "on-failure"
after = ["scheduler"]
[[node]]
name = "asker"
python = "{ROOT / 'examples/requesters.py'}:Requester"
params = {{ priority = 1, epoch = {EPOCH}, timeout = 3.0, start = 1.0, pause = 1.0, count = 1, setpoint = {SETPOINT} }}
after = ["scheduler", "reader"]
[[bind]]
from = "asker.req"
to = "scheduler.req[0]"
[[bind]]
from = "scheduler.ack[0]"
to = "asker.ack"
[[bind]]
from = "scheduler.mdl_command"
to = "reader.mdl_command"
""")
    return path


class CommandsTaken:
    """Counts the mdl_command inputs in the reader's published `@trace` bursts."""

    def __init__(self, observer: Observer):
        self.count = 0
        self.changed = threading.Condition()
        self.sub = observer.session.declare_subscriber(wire.trace_key("reader", "reader"), self._on_trace)

    def _on_trace(self, sample):
        for event in wire.trace_events(wire.decode(sample.payload.to_bytes())):
            if event.get("kind") == "input" and event.get("action") == "mdl_command":
                with self.changed:
                    self.count += 1
                    self.changed.notify_all()

    def wait(self, count: int, timeout: float) -> bool:
        with self.changed:
            return self.changed.wait_for(lambda: self.count >= count, timeout)


def test_a_killed_reader_of_mdl_command_gets_the_masters_program_again(tmp_path):
    port = free_port()
    path = system_file(tmp_path, port)
    output = tmp_path / "reader.mcap"
    observer = Observer("reader", f"tcp/127.0.0.1:{port}")
    taken = CommandsTaken(observer)
    try:
        with launcher(path, "-o", str(output), "--until", str(EPOCH + 4), "--after-live") as proc:
            assert observer.wait_all_alive(("scheduler", "reader", "asker"), 30), proc.output.read_text()
            assert taken.wait(1, 30), ("the reader never took the program", proc.output.read_text())
            reader = next(pid for pid, cmd in children_of(proc.pid).items() if "reader.json" in cmd)
            os.kill(reader, signal.SIGKILL)
            assert taken.wait(2, 30), ("the restarted reader never got the program again", proc.output.read_text())
            assert proc.wait(60) == 0, proc.output.read_text()
    finally:
        taken.sub.undeclare()
        observer.close()
    recording = read_recording(output)
    assert recording.complete
    events = recording.launcher_events()
    assert [e["code"] for e in events if e["node"] == "reader" and e["event"] == "exit"][:1] == [-signal.SIGKILL]
    assert [e for e in events if e["node"] == "reader" and e["event"] == "live" and e["restarts"] == 1], events

    scheduler = recording.trace("scheduler")
    notices = [e for e in scheduler if e["kind"] == "input" and e["action"] == "peer_restart"]
    assert [e["value"] for e in notices] == ["mdl_command"], scheduler   # the asker never restarted: no notice
    sent = [e for e in scheduler if e["kind"] == "output" and e["action"] == "mdl_command"]
    assert [e["value"]["w"] for e in sent] == [SETPOINT, SETPOINT], scheduler
    assert sent[0]["t"] < notices[0]["t"] <= sent[1]["t"] <= max(notices[0]["t"], sent[0]["t"] + 1.0) + 0.5

    # what the restarted reader took: its inputs after the kill (in the nodes' clock, from the
    # first start event; the new process's own start record may be missing, its first @trace
    # burst sent before its route to the recorder was made)
    reader = recording.trace("reader", starts=True)
    first = next(e for e in reader if e["kind"] == "start")
    died = next(e for e in events if e["node"] == "reader" and e["event"] == "exit")
    killed_t = died["t_ns"] / 1e9 - (first["value"]["wall"] - first["t"])
    taken_again = [e for e in reader if e["kind"] == "input" and e["action"] == "mdl_command" and e["t"] > killed_t]
    assert [e["value"]["w"] for e in taken_again] == [SETPOINT], (killed_t, reader)

    # the master commits when its epoch is over, counted over both signals (not restarted)
    commit = [e for e in scheduler if e["action"] == "ack" and e["kind"] == "output"]
    assert [e["value"] for e in commit] == ["COMMIT"], scheduler
    waited = max(0.0, sent[0]["t"] + 1.0 - notices[0]["t"])  # the re-send may wait out mdl_command's switching time
    assert abs(commit[0]["t"] - (sent[0]["t"] + EPOCH + waited)) < 0.1, (commit, sent, notices)
