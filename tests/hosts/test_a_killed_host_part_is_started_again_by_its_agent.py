"""A host's part killed mid-run (kill -9 of its launcher) is started again by its agent, and
the hub says so in one line and in its recording.

camera's launcher (`python -m iotad.launcher.run.host_part`, its agent's child) is killed once
camera's node `beat` has been live. Its agent, the part's supervisor, starts it again after a
backoff (a bounded number of times) from the same order; the hub prints one line
`host camera: its part was killed (exit -9); its agent starts it again ...`, records a
`host_part_restarted` event and `beat` down, and `beat` comes back: live again (the new
launcher's `live` event, in the hub's recording) and its outputs reach the hub's host after.
Before, the agent said "the run exited with -9", then "the hub is gone; waiting for the next
run", and the host's nodes were gone for the rest of the run (bench/bad_day.py, seed 9)."""
import os
import signal
import subprocess
import sys
import time

from agent_helpers import Lines, start
from launcher_helpers import ROOT
from namespaces import agent, hosts, hosts_header

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import read_recording

PORT, NET = 7681, 219
IOTAS = ROOT / "tests" / "system_iotas.py"
OUT = "iota/relaunch/beat/out"


def system_text(hub: str, camera: str) -> str:
    return hosts_header("relaunch", hub, PORT, "brain", "camera", camera) + f"""
[[node]]
name = "tick"
host = "brain"
python = "{IOTAS}:Pulse"
params = {{ period = 0.1 }}
[[node]]
name = "beat"
host = "camera"
python = "{IOTAS}:Pulse"
params = {{ period = 0.05 }}
"""


def wait_until(condition, run, timeout: float = 40) -> bool:
    """Poll `condition` (a question to the recording being written) while the run goes on."""
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline and run.poll() is None:
        time.sleep(0.2)
    return condition()


def heard(path, after: int = 0) -> bool:
    """The hub's recording so far holds an output of `beat` logged after `after` (ns)."""
    try:
        return any(m.topic == OUT and m.log_time > after for m in read_recording(path, salvage=True).messages)
    except (RecordingError, OSError, ValueError):
        return False


def restarted_and_heard(path) -> bool:
    """The hub's recording so far holds the restart, `beat` live after it and one of its outputs
    after that (read as it is written: the run goes on)."""
    try:
        recording = read_recording(path, salvage=True)
        events = recording.launcher_events()
    except (RecordingError, OSError, ValueError):
        return False
    restarted = [e["t_ns"] for e in events if e.get("event") == "host_part_restarted"]
    live = [e["t_ns"] for e in events if e.get("event") == "live" and e.get("node") == "beat"
            and restarted and e["t_ns"] > restarted[0]]
    return bool(live) and any(m.topic == OUT and m.log_time > live[0] for m in recording.messages)


def test_a_killed_host_part_is_started_again_by_its_agent_and_its_node_heard_again(tmp_path):
    recording = tmp_path / "relaunch.mcap"
    with hosts("brain", "camera", net=NET) as net:
        hub = net.addresses[("brain", "camera")]
        path = tmp_path / "relaunch.toml"
        path.write_text(system_text(hub, net.addresses["camera"]))
        with agent(net, "camera", f"tcp/{hub}:{PORT}"):
            run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure", "--plain",
                                 "--until", "120", "-o", str(recording)))
            out = Lines(run)
            try:
                # beat ran (camera's start gate open, its outputs in the hub's recording) before the kill
                assert out.wait_for("beat: live (on another host)", 60), out.text()[-3000:]
                assert wait_until(lambda: heard(recording), run), out.text()[-3000:]
                part = next(line for line in out.lines if line and "host camera: its agent runs its nodes (pid" in line)
                pid = int(part.rsplit("(pid ", 1)[1].split(")")[0])
                os.kill(pid, signal.SIGKILL)  # the launcher alone: its agent and the hub go on
                assert out.wait_for("host camera: its part was killed (exit -9); its agent starts it again", 30), \
                    out.text()[-3000:]
                # the new part's node live and heard at the hub, from the hub's own recording
                wait_until(lambda: restarted_and_heard(recording), run)
                run.send_signal(signal.SIGINT)
                run.wait(60)
            finally:
                interrupt_then_kill(run)
    text = out.text()
    assert run.returncode == 130, text[-3000:]  # the SIGINT that ended it; the restart failed nothing
    line = ("host camera: its part was killed (exit -9); its agent starts it again in 0.5 s (restart 1 of 3); "
            "its nodes (beat) are down until they are live again")
    assert text.count(line) == 1, text[-3000:]
    assert text.count("beat: live (on another host)") >= 2, text[-3000:]  # live, then live again
    assert "its part exited" not in text and "LOST" not in text, text[-3000:]
    assert "host camera: exit 130 (stopped by this run; killed 1 time(s), started again by its agent)" in text, \
        text[-3000:]

    rec = read_recording(recording)
    events = rec.launcher_events()
    restarted = [e for e in events if e.get("event") == "host_part_restarted"]
    assert len(restarted) == 1, events
    assert restarted[0]["message"] == line and restarted[0]["restarted_host"] == "camera", restarted
    assert restarted[0]["code"] == -9 and restarted[0]["attempt"] == 1, restarted
    t = restarted[0]["t_ns"]
    down = [e for e in events if e.get("event") == "down" and e.get("node") == "beat"]
    assert len(down) == 1 and down[0]["t_ns"] >= t, down
    live = [e for e in events if e.get("event") == "live" and e.get("node") == "beat"]
    assert len(live) == 2 and live[0]["t_ns"] < t < live[1]["t_ns"], live  # the first part's, the new one's
    assert live[0]["pid"] != live[1]["pid"], live  # a new node process of a new launcher
    after = [m for m in rec.messages if m.topic == OUT and m.log_time > live[1]["t_ns"]]
    assert after, sorted(rec.topics())  # its outputs reached the hub's host again
    assert not [e for e in events if e.get("event") == "host_failed"], events
