"""Delay and a bandwidth limit between hosts are violations, recorded and named, not crashes. A
source on brain sends every 20 ms (its switching time) to a sink on arm that accepts one input
per 20 ms; the link from brain to arm is shaped by a token bucket far below what crosses it (tc
tbf: this kernel has no netem), so messages queue, are lost and retransmitted, and arrive late
and bunched. The sink rejects those that come closer together than its switching time: each is
a `switching_time` violation in the hub's recording, naming the channel, and the run goes on to
its end and stops cleanly."""
import subprocess
import sys

from launcher_helpers import ROOT
from namespaces import hosts
from iotad.launcher.processes import interrupt_then_kill

IOTAS = ROOT / "tests" / "system_iotas.py"


def system(hub: str, arm: str) -> str:
    return f"""
[system]
name = "slow"
time_unit = 0.02
hub_host = "brain"
[system.endpoints]
listen = ["tcp/{hub}:7617"]
[hosts.brain]
listen = ["tcp/{hub}:0"]
[hosts.arm]
listen = ["tcp/{arm}:0"]

[[node]]
name = "source"
host = "brain"
python = "{IOTAS}:Source"
after = ["sink"]

[[node]]
name = "sink"
host = "arm"
python = "{IOTAS}:Sink"

[[bind]]
from = "source.out"
to = "sink.inp"
"""


def test_a_slow_link_makes_switching_time_violations_recorded_and_named(tmp_path):
    from iotad.recording.mcap_reader import read_recording

    with hosts("brain", "arm", net=207) as net:
        hub = net.addresses[("brain", "arm")]
        net.limit("brain", "arm", rate="48kbit", burst="1600", latency="100ms")
        path = tmp_path / "slow.toml"
        path.write_text(system(hub, net.addresses["arm"]))
        agent = subprocess.Popen(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                                          "--connect", f"tcp/{hub}:7617"),
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                                 start_new_session=True)
        run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--until", "10", "--after-live",
                                        "--plain", "-o", str(tmp_path / "slow.mcap")),
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                               start_new_session=True)
        try:
            output = run.communicate(timeout=90)[0]
        finally:
            interrupt_then_kill(run)
            interrupt_then_kill(agent)
    done = run
    assert done.returncode == 0 and "Traceback" not in output, output[-3000:]
    recording = read_recording(tmp_path / "slow.mcap")
    violations = [m.value for m in recording.messages if m.topic == "iota/slow/sink/@trace"
                  and m.value.get("kind") == "violation"]
    codes = {v["value"]["violation"] for v in violations}
    assert codes == {"switching_time"} and all(v["action"] == "inp" for v in violations), violations[:5]
    inputs = [m.value for m in recording.messages if m.topic == "iota/slow/sink/@trace" and m.value.get("kind") == "input"]
    assert len(violations) >= 5 and len(inputs) >= 5, (len(violations), len(inputs))
    print(f"{len(inputs)} inputs taken, {len(violations)} refused as too close")
    assert "sink" in output and "switching time" in output, output[-3000:]
