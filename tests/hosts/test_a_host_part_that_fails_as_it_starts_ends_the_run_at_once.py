"""A host's part that fails as it starts ends the whole run at once, with one line saying why.

arm's two nodes share a socketcan bus that arm's kernel does not have: each node host exits 2
(a configuration error, which no restart mends), arm's launcher gives both up and, with no node
left, exits; its agent tells the hub. Before, the hub took the exit in, said nothing and ran on
to its --until (with --after-live, for ever): a test waiting for every host's start gate waited
its whole timeout (the three-host tests: 90 s). Now the hub stops every node at once: `host arm:
its part exited with 1 before pinger, echo, can0 had been live ... stopping every node`, recorded as a
`host_failed` launcher event, exit status 1.

The bound is the mechanism's, read from the hub's own recording: the hub's `host_failed` comes
after arm's launcher gave its nodes up (its `giveup` events, which reach the hub's recorder) and
within the system's `start_timeout` of them, the time after which, before, the first thing that
could have noticed anything (a node that never showed its token) would have."""
import subprocess
import sys

from launcher_helpers import ROOT
from namespaces import agent, hosts, hosts_header

from iotad.recording.mcap_reader import read_recording

PORT, NET = 7669, 218
START_TIMEOUT = 30.0
IOTAS = ROOT / "tests" / "system_iotas.py"


def system_text(hub: str, arm: str) -> str:
    header = hosts_header("fails", hub, PORT, "brain", "arm", arm)
    header = header.replace('hub_host = "brain"\n', f'hub_host = "brain"\nstart_timeout = {START_TIMEOUT}\n')
    return header + f"""
[[node]]
name = "tick"
host = "brain"
python = "{IOTAS}:Pulse"
params = {{ period = 0.1 }}
[[node]]
name = "pinger"
host = "arm"
python = "{IOTAS}:CanPinger"
params = {{ period = 0.1 }}
[[node]]
name = "echo"
host = "arm"
python = "{IOTAS}:CanEcho"

[[can]]
name = "can0"
interface = "socketcan"
channel = "vcan0"
stations = ["pinger", "echo"]
"""


def test_a_host_part_that_fails_as_it_starts_ends_the_run_at_once_saying_why(tmp_path):
    recording = tmp_path / "fails.mcap"
    with hosts("brain", "arm", net=NET) as net:
        hub = net.addresses[("brain", "arm")]
        path = tmp_path / "fails.toml"
        path.write_text(system_text(hub, net.addresses["arm"]))
        with agent(net, "arm", f"tcp/{hub}:{PORT}"):
            # --until far beyond the bound: before, the run lasted all of it
            done = subprocess.run(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure",
                                           "--plain", "--until", "600", "--after-live", "-o", str(recording)),
                                  capture_output=True, text=True, timeout=300, cwd=ROOT)
    out = done.stdout
    assert done.returncode == 1, out[-3000:] + done.stderr[-2000:]
    # arm's own lines say why its nodes failed; the hub's one line says what it does about it
    assert any("[arm]" in text and "pinger: failed for good: exit 2 is a configuration error" in text
               for text in out.splitlines()), out[-3000:]
    # (the bus can0 is a node of arm's too, which never ran for want of its stations)
    line = ("host arm: its part exited with 1 before pinger, echo, can0 had been live (its lines above say why): "
            "stopping every node")
    assert out.count(line) == 1, out[-3000:]
    assert "  host arm: exit 1\n" in out, out[-3000:]  # the summary

    events = read_recording(recording).launcher_events()
    gave_up = [e["t_ns"] for e in events if e.get("event") == "giveup" and e.get("node") in ("pinger", "echo")]
    failed = [e for e in events if e.get("event") == "host_failed"]
    assert len(gave_up) == 2 and len(failed) == 1, events
    assert failed[0]["message"] == line and failed[0]["failed_host"] == "arm", failed
    waited = (failed[0]["t_ns"] - max(gave_up)) / 1e9
    assert 0 <= waited < START_TIMEOUT, waited
    # the hub's own node ran, and was stopped by the hub then, not left to run to the --until
    assert any(e.get("event") == "live" and e.get("node") == "tick" for e in events), events
    stopped = [e for e in events if e.get("event") == "exit" and e.get("node") == "tick"]
    assert len(stopped) == 1 and stopped[0]["code"] == 0 and stopped[0]["t_ns"] > failed[0]["t_ns"], stopped


def test_a_node_that_fails_for_good_on_another_host_does_not_hold_the_run(tmp_path):
    """arm's part runs on (a pulse of its own is live), its two CAN stations given up: the hub
    hears arm's launcher give them up (its `giveup` events) and counts them as ended, as it does
    its own nodes that failed for good: --after-live's seconds begin, the run ends, exit 1.
    Before, the hub waited for their liveliness for ever."""
    text = system_text("{hub}", "{arm}") + f"""
[[node]]
name = "beat"
host = "arm"
python = "{IOTAS}:Pulse"
params = {{ period = 0.1 }}
"""
    with hosts("brain", "arm", net=NET) as net:
        hub = net.addresses[("brain", "arm")]
        path = tmp_path / "fails.toml"
        path.write_text(text.replace("{hub}", hub).replace("{arm}", net.addresses["arm"]))
        with agent(net, "arm", f"tcp/{hub}:{PORT}"):
            done = subprocess.run(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure",
                                           "--plain", "--until", "2", "--after-live", "--no-record"),
                                  capture_output=True, text=True, timeout=300, cwd=ROOT)
    out = done.stdout
    assert done.returncode == 1, out[-3000:] + done.stderr[-2000:]
    assert "every node is live: --until 2 s counts from now" in out, out[-3000:]
    assert "--until 2 s after every node was live reached: stopping" in out, out[-3000:]
    assert "its part exited" not in out, out[-3000:]  # arm's part ran on: beat was live
    for name in ("can0", "echo", "pinger"):
        assert (f"  {name}: FAILED FOR GOOD on host arm (its lines above say why); the run's exit status is 1"
                in out), out[-3000:]
    assert "  host arm: exit 130 (stopped by this run)" in out, out[-3000:]
