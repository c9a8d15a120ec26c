"""A host cut off from the hub goes on recording its own nodes: a source on host arm feeds a sink on
host brain (the hub), one `iotad run --host` per namespace, each with `-o`. The link between them
is cut for 3 s mid-run. The arm's own recording holds every event its source fired, those of
the cut included, each recorded as it happened (not when the link came back); whatever the hub's
recording lacks of them is inside a gap the merge marks, naming the arm (over TCP a 3 s cut
loses nothing at the hub: its events arrive late; tests/recording/ has merges of a hub that
lacks them); the merged recording holds them all once."""
import time

from launcher_helpers import launcher
from namespaces import hosts
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merge

CUT = 3.0  # s the link is down


def system(hub: str, arm: str) -> str:
    from launcher_helpers import ROOT
    iotas = ROOT / "tests" / "system_iotas.py"
    return f"""
[system]
name = "cut"
hub_host = "brain"
[system.endpoints]
listen = ["tcp/{hub}:7619"]
[hosts.brain]
listen = ["tcp/{hub}:0"]
[hosts.arm]
listen = ["tcp/{arm}:0"]

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


def wait_for(path, text: str, deadline: float = 60.0) -> None:
    end = time.monotonic() + deadline
    while time.monotonic() < end:
        if text in path.read_text(errors="replace"):
            return
        time.sleep(0.05)
    raise AssertionError(f"no {text!r} in {path} within {deadline:g} s:\n{path.read_text(errors='replace')[-3000:]}")


def outputs(recording) -> dict:
    """The source's output events by their value n: (t, the message's log time)."""
    return {m.value["value"]: (m.value["t"], m.log_time) for m in recording.messages
            if m.topic == "iota/cut/source/@trace" and m.value.get("kind") == "output"}


def test_a_host_cut_off_from_the_hub_keeps_recording_and_the_merge_marks_what_the_hub_missed(tmp_path):
    with hosts("brain", "arm", net=207) as net:
        path = tmp_path / "cut.toml"
        path.write_text(system(net.addresses[("brain", "arm")], net.addresses["arm"]))
        hub_file, arm_file = tmp_path / "cut.mcap", tmp_path / "cut.arm.mcap"
        with launcher(path, "--host", "brain", "--until", "30", "-o", str(hub_file),
                      prefix=tuple(net.exec("brain"))) as brain:
            wait_for(brain.output, "hub: ")
            with launcher(path, "--host", "arm", "--until", "30", "-o", str(arm_file),
                          prefix=tuple(net.exec("arm"))) as arm:
                wait_for(arm.output, "start gate open")
                wait_for(arm.output, "recording to")
                net.cut("brain", "arm")
                cut_at = time.time()
                try:
                    time.sleep(CUT)  # the partition itself: how long the arm is on its own
                finally:
                    net.heal("brain", "arm")
                healed_at = time.time()
                arm.send_signal(2)
                assert arm.wait(30) in (0, 130), arm.output.read_text()[-3000:]
            brain.send_signal(2)
            brain.wait(30)
    own, hubs = read_recording(arm_file), read_recording(hub_file)
    origin = own.info["run"]["origin"]
    fired = outputs(own)
    # every event of the source, one per second from n=0, none missing from its own recording
    assert sorted(fired) == list(range(len(fired))), fired
    during = [n for n, (t, _) in fired.items() if cut_at - origin + 0.1 < t < healed_at - origin - 0.1]
    assert len(during) >= 2, (fired, cut_at - origin, healed_at - origin)
    # each recorded as it happened (the arm's clock is the hub's here): within a second of its t,
    # not when the link came back
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
