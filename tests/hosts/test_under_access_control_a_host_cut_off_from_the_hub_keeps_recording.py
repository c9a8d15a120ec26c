"""A host cut off from the hub goes on recording under access control: a source on host arm feeds
a sink on host brain (the hub), linked by TLS and started by one `iotad run --certs -o cut.mcap`
through arm's agent. The link is cut for 3 s mid-run. Arm's nodes and recorder are clients of
arm's own router (its launcher), not of the hub, so arm's recording holds every event its source
fired, those of the cut included, each recorded as it happened; whatever the hub's recording
lacks of them is inside a gap the merge marks, naming arm; the merged recording holds them all."""
import sys
import time

from agent_helpers import Lines, authority_for, start
from launcher_helpers import ROOT
from namespaces import hosts

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merge

PORT = 7632
CUT = 3.0  # s the link is down


def system(hub: str, arm: str) -> str:
    iotas = ROOT / "tests" / "system_iotas.py"
    return f"""
[system]
name = "cut"
hub_host = "brain"
[system.endpoints]
listen = ["tls/{hub}:{PORT}"]
[hosts.brain]
listen = ["tls/{hub}:0"]
[hosts.arm]
listen = ["tls/{arm}:0"]

[[node]]
name = "source"
host = "arm"
python = "{iotas}:Source"
params = {{ period = 1.0 }}
[[node]]
name = "sink"
host = "brain"
python = "{iotas}:FreeSink"

[[bind]]
from = "source.out"
to = "sink.inp"
"""


def outputs(recording) -> dict:
    """The source's output events by their value n: (t, the message's log time)."""
    return {m.value["value"]: (m.value["t"], m.log_time) for m in recording.messages
            if m.topic == "iota/cut/source/@trace" and m.value.get("kind") == "output"}


def test_under_access_control_a_host_cut_off_keeps_recording_and_the_merge_marks_what_the_hub_missed(tmp_path):
    hub_file, arm_file = tmp_path / "cut.mcap", tmp_path / "cut.arm.mcap"
    with hosts("brain", "arm", net=209) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm]})
        path = tmp_path / "cut.toml"
        path.write_text(system(hub, arm))
        agent = start(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                               "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs)))
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                             "--certs", str(certs), "--until", "60", "-o", str(hub_file)))
        lines = Lines(run)
        try:
            assert lines.wait_for(f"recording to {arm_file}", 90), lines.text()[-4000:]
            assert lines.wait_for("source: live (on another host)", 60), lines.text()[-4000:]
            deadline = time.monotonic() + 60  # both hosts' start gates open: the source fires
            while lines.text().count("start gate open") < 2 and time.monotonic() < deadline and run.poll() is None:
                time.sleep(0.1)
            assert lines.text().count("start gate open") == 2, lines.text()[-4000:]
            net.cut("brain", "arm")
            cut_at = time.time()
            try:
                time.sleep(CUT)  # the partition itself: how long the arm is on its own
            finally:
                net.heal("brain", "arm")
            healed_at = time.time()
            time.sleep(1.0)  # a second of the healed link, for what waited in it
        finally:
            code = interrupt_then_kill(run)
            interrupt_then_kill(agent)
    output = lines.text()
    assert code == 130, output[-4000:]
    assert "access control: on (" in output, output[-4000:]
    own, hubs = read_recording(arm_file), read_recording(hub_file)
    origin = own.info["run"]["origin"]
    fired = outputs(own)
    # every event of the source, from n=0, none missing from its own recording
    assert sorted(fired) == list(range(len(fired))), fired
    during = [n for n, (t, _) in fired.items() if cut_at - origin + 0.1 < t < healed_at - origin - 0.1]
    assert len(during) >= 2, (fired, cut_at - origin, healed_at - origin)
    # each recorded as it happened (the arm's clock is the hub's here), not when the link came back
    for n in during:
        t, log_time = fired[n]
        assert 0 <= log_time / 1e9 - origin - t < 1.0, (n, t, log_time / 1e9 - origin)
    merged = merge([hub_file, arm_file])
    joined = outputs(merged.recording)  # log times on the hub's clock
    assert sorted(joined) == sorted(fired)
    missed = sorted(n for n in fired if n not in outputs(hubs))
    gaps = [g for g in merged.gaps if g["host"] == "arm" and "did not reach the hub" in g["reason"]]
    for n in missed:  # whatever the hub lacks is inside a gap that names the arm
        t_ns = joined[n][1]
        assert any(g["from_ns"] <= t_ns <= g["to_ns"] for g in gaps), (n, missed, gaps)
    assert sum(g["events"] for g in gaps) >= len(missed)
