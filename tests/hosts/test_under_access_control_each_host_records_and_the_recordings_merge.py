"""Each host records its own part under access control too: the Figure 2 scheduler on brain (the
hub) and a requester on arm, linked by TLS and started by one `iotad run --certs -o secure.mcap`
through arm's agent. Arm's launcher is the router of arm's nodes and recorder (on a private unix
socket, with the hub's rights for each of them) and reaches the hub as arm's launcher user; it
records arm's part to secure.arm.mcap on arm. The run says access control is on and where the
host's file is; `iotad merge` joins the two files into one that holds both hosts' events, and
`iotad check` finds it clean."""
import json
import re
import subprocess
import sys

from agent_helpers import Lines, authority_for, start
from launcher_helpers import ROOT
from namespaces import hosts, split_figure2
from recorded_systems import check_of_a_real_run

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_reader import read_recording

PORT = 7631


def traced(recording, node: str) -> set:
    return {(m.publish_time, m.sequence, m.data) for m in recording.messages if m.topic == f"iota/split/{node}/@trace"}


def test_under_access_control_each_host_records_its_part_and_the_merge_holds_both(tmp_path):
    with hosts("brain", "arm", net=208) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm]})
        path = tmp_path / "split.toml"
        path.write_text(split_figure2("split", hub, PORT, "brain", "arm", arm, "tls", count=3))
        recording = tmp_path / "secure.mcap"
        agent = start(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                               "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs)))
        agent_lines = Lines(agent)
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                             "--certs", str(certs), "--until", "7", "--after-live", "-o", str(recording)))
        lines = Lines(run)
        try:
            assert lines.wait_for("vision: live (on another host)", 90), lines.text()[-4000:]
            # the hub's tools reach arm's node through arm's router: its spec answers, naming its host
            listed = subprocess.run(net.exec("brain", "env", f"IOTAD_CERTS={certs}", "IOTAD_CERTS_HOST=brain",
                                             sys.executable, "-m", "iotad", "ls", "--system", "split", "--json",
                                             "--connect", f"tls/{hub}:{PORT}"),
                                    capture_output=True, text=True, timeout=60, cwd=ROOT)
            code = run.wait(150)
            lines.wait_for("join them with: iotad merge", 30)  # the summary's last line, or the end of the output
        finally:
            interrupt_then_kill(run)
            interrupt_then_kill(agent)
    output = lines.text()
    assert code == 0, output[-4000:] + agent_lines.text()[-2000:]
    hosts_of = {entry["path"]: entry["host"] for entry in map(json.loads, listed.stdout.splitlines())}
    assert hosts_of == {"scheduler": "brain", "vision": "arm"}, listed.stdout + listed.stderr
    assert "access control: on (" in output and "access control is OFF" not in output, output[-4000:]
    arm_path = tmp_path / "secure.arm.mcap"
    assert f"recording to {arm_path}" in output, output[-4000:]
    assert f"join them with: iotad merge {recording} {arm_path}" in output, output[-4000:]
    hub_file, arm_file = read_recording(recording), read_recording(arm_path)
    assert arm_file.info["run"]["host"] == "arm" and arm_file.info["run"]["origin"] == hub_file.info["run"]["origin"]
    # arm's recorder heard arm's node through arm's router, with the acks it took from brain's scheduler
    assert traced(arm_file, "vision"), "the arm's own recording holds vision's events"
    taken = [e.get("value") for e in arm_file.trace("vision") if e["kind"] == "input"]
    assert "COMMIT" in taken, taken
    # what crosses the link to arm is only what arm's nodes may read: no trace of brain's nodes
    assert not traced(arm_file, "scheduler")

    merged_path = tmp_path / "secure.merged.mcap"
    joined = subprocess.run([sys.executable, "-m", "iotad", "merge", str(recording), str(arm_path), "-o", str(merged_path)],
                            capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert joined.returncode == 0, joined.stdout + joined.stderr
    merged = read_recording(merged_path)
    for node, files in (("vision", (arm_file, hub_file)), ("scheduler", (hub_file,))):
        held = set().union(*(traced(f, node) for f in files))
        assert held and traced(merged, node) == held, node
    acks = [m.value for m in merged.messages if m.topic == "iota/split/scheduler/ack/0"]
    assert "COMMIT" in acks, acks
    out = check_of_a_real_run(merged_path)
    assert "merged from secure.mcap, secure.arm.mcap" in out, out[-3000:]
    assert re.search(r"vision: \d+ events, [1-9]\d* firings checked", out), out[-3000:]
