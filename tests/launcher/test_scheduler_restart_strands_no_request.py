"""kill -9 of the Figure 2 scheduler while one request is signalling (it holds the motors) and
another is pending (it waits for them): the launcher restarts the scheduler, which starts empty;
each requester sees the restart through the scheduler's liveliness (its `peer_restart` input),
takes the request in flight as an ABORT and goes on with its script. Real processes under
`iotad run`; the kill is triggered by the pending request itself, seen on the wire; every
assertion is read from the recording (split in files of one second, read as one)."""
import os
import signal
import threading
import time
from pathlib import Path

from iotad.node_host import wire
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import ROOT, Observer, children_of, free_port, launcher

SLACK = 1.0  # seconds for liveliness to travel and a loaded machine to schedule the requester

# The engines start together (the launcher's start gate). hi asks 2 s after that (time for every
# route to the observer to be made) and holds the motors for 3 s; lo asks a second later, so
# after hi, with a lower priority: it stays pending
PARAMS = {"hi": dict(priority=5, epoch=3.0, timeout=3.0, start=2.0, pause=0.5, count=2, setpoint=1.5),
          "lo": dict(priority=1, epoch=0.5, timeout=3.0, start=3.0, pause=0.5, count=2, setpoint=0.2)}
AFTER = {"hi": '["scheduler"]', "lo": '["scheduler", "hi"]'}
MDL_SWITCHING = 1.0  # the scheduler's mdl_command: a motion may wait this long for its command


def system_file(tmp_path: Path, port: int) -> Path:
    nodes = "".join(f"""
[[node]]
name = "{name}"
python = "{ROOT / 'examples/requesters.py'}:Requester"
params = {{ {', '.join(f'{k} = {v}' for k, v in params.items())} }}
after = {AFTER[name]}
[[bind]]
from = "{name}.req"
to = "scheduler.req[{index}]"
[[bind]]
from = "scheduler.ack[{index}]"
to = "{name}.ack"
""" for index, (name, params) in enumerate([("lo", PARAMS["lo"]), ("hi", PARAMS["hi"])]))
    path = tmp_path / "restart.toml"
    path.write_text(f"""
[system]
name = "restart"
time_unit = 1.0
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]
[[node]]
name = "scheduler"
spec = "{ROOT / 'nodes/scheduler/scheduler.iota'}"
params = {{ N = 2, T = 0.5 }}
restart = "on-failure"
{nodes}""")
    return path


class Traces:
    """What the nodes say they did, from their published `@trace` bursts (so the recording holds
    it too): (node, what) in arrival order; a requester's `req` or `last req` (sent) and `answer`
    (an ack or a restart notice taken in), and the scheduler's `has lo's req`."""

    def __init__(self, observer: Observer):
        self.seen: list[tuple[str, str]] = []
        self.changed = threading.Condition()
        self.subs = [observer.session.declare_subscriber(wire.trace_key("restart", node), self._on_trace(node))
                     for node in ("scheduler", "lo", "hi")]

    def _on_trace(self, node: str):
        def on_trace(sample):
            for event in wire.trace_events(wire.decode(sample.payload.to_bytes())):
                kind, action = event.get("kind"), event.get("action")
                what = None
                if node == "scheduler" and kind == "input" and action == "req" and event.get("index") == 0 \
                        and event.get("seq") == 0:  # lo's first request
                    what = "has lo's req"
                elif node != "scheduler" and kind == "output" and action == "req":
                    # numbered from 0 on the wire: the last one is known even if a burst sent
                    # before this observer's route to a new node existed never reached it
                    what = "last req" if event.get("seq") == PARAMS[node]["count"] - 1 else "req"
                elif node != "scheduler" and kind == "input" and action in ("ack", "peer_restart"):
                    what = "answer"
                if what is not None:
                    with self.changed:
                        self.seen.append((node, what))
                        self.changed.notify_all()
        return on_trace

    def wait(self, predicate, timeout: float) -> bool:
        with self.changed:
            return self.changed.wait_for(lambda: predicate(list(self.seen)), timeout)

    def close(self):
        for sub in self.subs:
            sub.undeclare()


def finished(seen) -> bool:
    """Each requester has sent its last request and taken in an answer after it."""
    for who in PARAMS:
        mine = [what for name, what in seen if name == who]
        if "last req" not in mine or "answer" not in mine[mine.index("last req"):]:
            return False
    return True


def test_kill_9_of_the_scheduler_while_pending_and_signalling_strands_no_request(tmp_path):
    port = free_port()
    path = system_file(tmp_path, port)
    output = tmp_path / "restart.mcap"
    observer = Observer("restart", f"tcp/127.0.0.1:{port}")
    traces = Traces(observer)
    try:
        # a long run's recording: split every second (`iotad run --max-duration`), read as one
        with launcher(path, "-o", str(output), "--max-duration", "1", "--until", "60") as proc:
            assert observer.wait_all_alive(("scheduler", "lo", "hi"), 30), proc.output.read_text()
            # lo's first request, once in the scheduler's published trace, is the moment: hi
            # signals (lo started after it and waits as long) and lo is pending
            assert traces.wait(lambda seen: ("scheduler", "has lo's req") in seen, 30), \
                ("the observer never saw the scheduler take lo's first request", traces.seen, proc.output.read_text())
            scheduler = next(pid for pid, cmd in children_of(proc.pid).items() if "scheduler.json" in cmd)
            os.kill(scheduler, signal.SIGKILL)
            assert traces.wait(finished, 40), (traces.seen, proc.output.read_text())
            proc.send_signal(signal.SIGINT)
            assert proc.wait(30) == 130, proc.output.read_text()
    finally:
        traces.close()
        observer.close()
    recording = read_recording(output)
    assert recording.complete and len(recording.files) >= 2, recording.files
    events = recording.launcher_events()
    died = [e for e in events if e["node"] == "scheduler" and e["event"] == "exit" and e["code"] == -signal.SIGKILL]
    assert len(died) == 1, events
    back = [e for e in events if e["node"] == "scheduler" and e["event"] == "live" and e["restarts"] == 1]
    assert len(back) == 1, events
    restart_time = (back[0]["t_ns"] - died[0]["t_ns"]) / 1e9

    # node times -> wall clock, from each node's start event (first run of the scheduler)
    starts = {}
    for event in recording.trace(starts=True):
        if event["kind"] == "start":
            starts.setdefault(event["node"], event["value"]["wall"] - event["t"])
    killed_t = died[0]["t_ns"] / 1e9 - starts["scheduler"]

    # at the kill: the scheduler had both requests, commanded hi's motion and answered neither
    before = [e for e in recording.trace("scheduler") if e["t"] < killed_t]
    inputs = {e["index"] for e in before if e["kind"] == "input" and e["action"] == "req"}
    assert inputs == {0, 1}, before
    assert [e["value"]["w"] for e in before if e["action"] == "mdl_command"] == [PARAMS["hi"]["setpoint"]]
    assert not [e for e in before if e["action"] == "ack"], before

    for who, params in PARAMS.items():
        trace = sorted(recording.trace(who), key=lambda e: e["t"])
        asked, answers = None, []
        for event in trace:
            if event["kind"] == "output" and event["action"] == "req":
                assert asked is None, f"{who} asked again before an answer: {trace}"
                asked = event["t"]
            elif event["kind"] == "input" and event["action"] in ("ack", "peer_restart") and asked is not None:
                if event["action"] == "peer_restart":  # the request the kill stranded: answered by the restart
                    answer, limit = "ABORT (restart)", params["timeout"] + restart_time + SLACK
                else:  # a request the live scheduler answered: at the latest when its motion ends
                    answer, limit = event["value"], params["timeout"] + MDL_SWITCHING + params["epoch"] + SLACK
                answers.append(answer)
                assert event["t"] - asked <= limit, (who, answer, limit, trace)
                asked = None
        assert asked is None, f"{who}'s last request was never answered: {trace}"
        assert len(answers) == params["count"], (who, answers)  # its script ran to its end
        assert answers[0] == "ABORT (restart)", (who, answers)  # the request in flight at the kill
        assert answers[-1] in ("COMMIT", "ABORT", "REJECT"), (who, answers)
