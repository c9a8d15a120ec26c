"""The paper's Figure 2 split over two hosts (network namespaces) and started by one `iotad run`:
the scheduler and the manipulation requester on host brain (the hub), the vision requester on host
arm through its agent. Each host records its own part (`-o split.mcap` on the hub: split.mcap
there, split.arm.mcap on the arm, with the arm's clock offset in it); `iotad merge` joins them.
The merged recording holds every event of both hosts' nodes, its acks are those of the same
system on one host (commits, an abort, a reject), and `iotad check` finds it clean."""
import subprocess
import sys
from pathlib import Path

from launcher_helpers import ROOT
from namespaces import agent, hosts
from recorded_systems import check_of_a_real_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merged_gaps

EXAMPLES = ROOT / "examples"


def figure2_over(hub: str, arm: str, port: int = 7617) -> str:
    """examples/figure2.toml with hosts: vision on arm, the rest on brain."""
    text = (EXAMPLES / "figure2.toml").read_text()
    text = text.split("[sweep]")[0]
    text = text.replace('name = "figure2"', 'name = "split2"\nhub_host = "brain"')
    text = text.replace('listen = ["tcp/127.0.0.1:7447"]', f'listen = ["tcp/{hub}:{port}"]')
    text = text.replace('spec = "../nodes/', f'spec = "{ROOT}/nodes/').replace('python = "requesters.py', f'python = "{EXAMPLES}/requesters.py')
    for node, host in (("scheduler", "brain"), ("vision", "arm"), ("manipulation", "brain")):
        text = text.replace(f'name = "{node}"\n', f'name = "{node}"\nhost = "{host}"\n')
    return text + f'\n[hosts.brain]\nlisten = ["tcp/{hub}:0"]\n[hosts.arm]\nlisten = ["tcp/{arm}:0"]\n'


def iotad(*args, place=lambda *c: list(c), timeout=180):
    return subprocess.run(place(sys.executable, "-m", "iotad", *map(str, args)), capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT)


def acks(recording, system: str) -> dict[str, list[str]]:
    return {str(k): [m.value for m in recording.messages if m.topic == f"iota/{system}/scheduler/ack/{k}"]
            for k in (0, 1)}


def traced(recording, node: str) -> set:
    return {(m.publish_time, m.sequence, m.data) for m in recording.messages if m.topic == f"iota/split2/{node}/@trace"}


def test_each_host_records_its_part_and_the_merged_recording_holds_both(tmp_path):
    with hosts("brain", "arm", net=206) as net:
        hub = net.addresses[("brain", "arm")]
        system = tmp_path / "split2.toml"
        system.write_text(figure2_over(hub, net.addresses["arm"]))
        with agent(net, "arm", f"tcp/{hub}:7617"):
            done = iotad("run", system, "--insecure", "--until", "9", "--after-live", "--plain", "-o", tmp_path / "split.mcap",
                         place=lambda *c: net.exec("brain", *c))
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    # the arm's launcher said where it records, on its own machine (here: the same folder)
    assert f"recording to {tmp_path / 'split.arm.mcap'}" in done.stdout, done.stdout[-3000:]
    assert f"join them with: iotad merge {tmp_path / 'split.mcap'} {tmp_path / 'split.arm.mcap'}" in done.stdout
    hub_file, arm_file = read_recording(tmp_path / "split.mcap"), read_recording(tmp_path / "split.arm.mcap")
    assert hub_file.info["run"]["hub"] is True and hub_file.info["run"]["host"] == "brain"
    arm_run = arm_file.info["run"]
    assert arm_run["host"] == "arm" and not arm_run["hub"] and arm_run["origin"] == hub_file.info["run"]["origin"]
    assert abs(arm_run["clock"]["offset"]) <= 0.005 and arm_run["clock"]["samples"] >= 1, arm_run
    assert traced(arm_file, "vision"), "the arm's own recording holds vision's events"
    # and only the arm's: the brain's nodes' traces do not cross the link to be recorded twice
    assert not traced(arm_file, "scheduler") and not traced(arm_file, "manipulation")

    merged_path = tmp_path / "split.merged.mcap"
    joined = iotad("merge", tmp_path / "split.mcap", tmp_path / "split.arm.mcap", "-o", merged_path)
    assert joined.returncode == 0, joined.stderr
    merged = read_recording(merged_path)
    # every event of every host's nodes, from whichever file held it
    for node, files in (("vision", (arm_file, hub_file)), ("scheduler", (hub_file,)), ("manipulation", (hub_file,))):
        held = set().union(*(traced(f, node) for f in files))
        assert traced(merged, node) == held and held, node
    # heartbeats (no sender's time) once each too, not once per recording that heard them
    beats = lambda r: [m.data for m in r.messages if m.topic == "iota/split2/vision/@heartbeat"]
    assert sorted(beats(merged)) == sorted(set(beats(hub_file)) | set(beats(arm_file)))
    # no stretch of the arm's events missed by the hub: the network held (the gaps, if any, say so)
    assert not [g for g in merged_gaps(merged) if "did not reach the hub" in g["reason"]], merged_gaps(merged)

    # commits and aborts as on one host: the same system in one process in virtual time, each
    # requester starting as late after the scheduler as it did here (each host's nodes start
    # once that host's own are live: the arm's some time after the brain's)
    starts = merged.start_times()
    late = {node: starts[node] - starts["scheduler"] for node in ("vision", "manipulation")}
    one_host = tmp_path / "one_host.toml"
    one_host.write_text(figure2_over(hub, net.addresses["arm"])
                        .replace("start = 0.5,", f"start = {0.5 + late['vision']:.4f},")
                        .replace("start = 1.5,", f"start = {1.5 + late['manipulation']:.4f},"))
    virtual = iotad("run", one_host, "--virtual", "--until", "30", "-o", tmp_path / "virtual.mcap")
    assert virtual.returncode == 0, virtual.stderr
    expected, got = acks(read_recording(tmp_path / "virtual.mcap"), "split2"), acks(merged, "split2")
    for k in ("0", "1"):
        assert got[k] and got[k] == expected[k][:len(got[k])], (k, late, got, expected)
    assert "COMMIT" in got["0"] + got["1"] and "ABORT" in got["0"] + got["1"], (late, got)

    out = check_of_a_real_run(merged_path)
    assert "merged from split.mcap, split.arm.mcap" in out, out[-3000:]
    for node in ("scheduler", "vision", "manipulation"):
        assert f"{node}: " in out and "NOT CHECKED" not in out, out[-3000:]
    replayed = iotad("replay", merged_path, "--node", "vision")
    assert replayed.returncode == 0 and "vision: replay agrees" in replayed.stdout, replayed.stdout + replayed.stderr
