"""Delay and a bandwidth limit between hosts are violations, recorded and named, not crashes. A
source on brain sends every 20 ms (its switching time) to a sink on arm that accepts one input
per 20 ms; the link from brain to arm is shaped by a token bucket far below what crosses it (tc
tbf: this kernel has no netem), so messages queue, are lost and retransmitted, and arrive late
and bunched. The sink rejects those that come closer together than its switching time: each is
a `switching_time` violation in the hub's recording, naming the channel, and the run goes on to
its end and stops cleanly."""
from launcher_helpers import ROOT
from namespaces import hosts
from partition_run import SplitRun, split_header
from iotad.recording.mcap_reader import read_recording

IOTAS = ROOT / "tests" / "system_iotas.py"


def system(hub: str, arm: str, port: int) -> str:
    return split_header("slow", hub, port, arm, "time_unit = 0.02") + f"""
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
    with hosts("brain", "arm", net=207) as net:
        hub, port = net.addresses[("brain", "arm")], 7617
        net.limit("brain", "arm", rate="48kbit", burst="1600", latency="100ms")
        run = SplitRun(net, tmp_path, port, "slow", system(hub, net.addresses["arm"], port),
                       run_args=("--until", "10", "--after-live", "-o", str(tmp_path / "slow.mcap")))
        try:
            run.start()
            code = run.procs["run"].wait(90)
        finally:
            run.stop()
        output = run.output()
    assert code == 0 and "Traceback" not in output, output[-3000:]
    recording = read_recording(tmp_path / "slow.mcap")
    violations = [m.value for m in recording.messages if m.topic == "iota/slow/sink/@trace"
                  and m.value.get("kind") == "violation"]
    codes = {v["value"]["violation"] for v in violations}
    assert codes == {"switching_time"} and all(v["action"] == "inp" for v in violations), violations[:5]
    inputs = [m.value for m in recording.messages if m.topic == "iota/slow/sink/@trace" and m.value.get("kind") == "input"]
    assert len(violations) >= 5 and len(inputs) >= 5, (len(violations), len(inputs))
    assert "sink" in output and "switching time" in output, output[-3000:]
    print(f"{len(inputs)} inputs taken, {len(violations)} refused as too close")
