"""A host whose agent disappears (killed: the machine gone) is reported by the hub's `iotad run`,
its nodes are marked down (a `down` launcher event each, in the recording), and its part dies
with its agent. When an agent of that host is back during the run, the hub gives it its part
again, and its nodes' peers on the other hosts get restart notices (`peer_restart`) as for a
local restart. `iotad ls` and `iotad top` name each node's host. In network namespaces: the Figure 2 scheduler on arm, the requester on brain."""
import json
import re
import signal
import subprocess
import sys

from launcher_helpers import ROOT, wait_until
from namespaces import hosts, split_figure2
from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_reader import read_recording


def system_text(hub: str, arm: str) -> str:
    """The Figure 2 scheduler on arm, the requester (asking on and on) on brain with the hub."""
    return split_figure2("lost", hub, 7645, "brain", "arm", arm, scheduler_on="arm", count=1000, pause=0.5)


def start_agent(net, hub: str) -> subprocess.Popen:
    return subprocess.Popen(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                                     "--connect", f"tcp/{hub}:7645"),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                            start_new_session=True)


def tool(net, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(net.exec("brain", sys.executable, "-m", "iotad", *args), capture_output=True, text=True,
                          timeout=60, cwd=ROOT)


def test_a_lost_host_is_reported_its_nodes_marked_down_and_its_return_restarts_them(tmp_path):
    recording = tmp_path / "lost.mcap"
    with hosts("brain", "arm", net=208) as net:
        hub = net.addresses[("brain", "arm")]
        path = tmp_path / "lost.toml"
        path.write_text(system_text(hub, net.addresses["arm"]))
        first = start_agent(net, hub)
        second = watch = None
        trace = tmp_path / "vision-trace.jsonl"
        log = tmp_path / "run.log"
        with log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure", "--plain",
                                            "-o", str(recording)),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
        try:
            assert wait_until(lambda: "vision: live (pid" in log.read_text()
                              and "scheduler: live (on another host)" in log.read_text(), 90), log.read_text()[-3000:]
            # ls and top name each node's host
            listed = tool(net, "ls", "--system", "lost", "--json", "--connect", f"tcp/{hub}:7645")
            assert listed.returncode == 0, listed.stderr
            hosts_of = {entry["path"]: entry["host"] for entry in map(json.loads, listed.stdout.splitlines())}
            assert hosts_of == {"scheduler": "arm", "vision": "brain"}, listed.stdout
            top = tool(net, "top", "--system", "lost", "--once", "2", "--connect", f"tcp/{hub}:7645")
            assert re.search(r"scheduler\s*│\s*arm\s*│\s*alive", top.stdout), top.stdout + top.stderr
            assert re.search(r"vision\s*│\s*brain\s*│\s*alive", top.stdout), top.stdout + top.stderr
            # the requester's events, to see it take the restart notice in before the run is stopped
            watch = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "echo", "iota/lost/vision/@trace",
                                              "--json", "--connect", f"tcp/{hub}:7645"),
                                     stdout=trace.open("w"), stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True)
            assert wait_until(lambda: trace.read_text().strip(), 30), "iotad echo saw none of the requester's events"
            first.send_signal(signal.SIGKILL)  # the agent alone: its run dies with it (parent-death signal)
            first.wait(10)
            assert wait_until(lambda: "scheduler: DOWN (host arm lost)" in log.read_text(), 60), log.read_text()[-3000:]
            second = start_agent(net, hub)
            back = wait_until(lambda: re.search(r"host arm: back; its nodes start again \(scheduler\)"
                                                r"[\s\S]*scheduler: live \(on another host\)", log.read_text()), 90)
            assert back, log.read_text()[-3000:]
            assert wait_until(lambda: '"peer_restart"' in trace.read_text(), 60), trace.read_text()[-2000:]
            run.send_signal(signal.SIGINT)
            code = run.wait(60)
        finally:
            interrupt_then_kill(run)
            for process in (first, second, watch):
                if process is not None:
                    interrupt_then_kill(process)
        output = log.read_text()
        assert code == 130, output[-3000:]
        assert "host arm LOST: its agent is gone" in output
        assert "host arm: its agent is back; giving it its part again" in output
        assert "host arm: exit 130 (stopped by this run; lost 1 time(s), back each time)" in output, output[-2000:]
        recorded = read_recording(recording)
        events = recorded.launcher_events()
        down = [e for e in events if e.get("event") == "down"]
        assert [(e["node"], e["host"]) for e in down] == [("scheduler", "arm")], down
        assert any(e.get("event") == "host_back" and e.get("host") == "arm" for e in events), events
        notices = [e for e in recorded.trace("vision") if e.get("kind") == "input" and e.get("action") == "peer_restart"]
        assert len(notices) == 1, [e for e in recorded.trace("vision") if e.get("kind") == "input"][-10:]
