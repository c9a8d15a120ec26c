"""Access control holds across hosts: the Figure 2 split over two namespaces, started by
one `iotad run --certs` on brain through arm's agent over TLS, runs with access control on
(arm's launcher gets its credentials from the hub through the agent, its node from arm's
router). A third namespace tries to open a session, publish on the scheduler's motor command
and a requester's output bound to the scheduler, and read every channel: without a
certificate, with another authority's, and with a certificate of the system's own authority
but no credentials, or with a guessed password. Each is refused, nothing of it reaches a
subscriber or the recording, and the run commits and checks clean. The control: the same
script with the tools' credentials opens a session and reads."""
import re
import subprocess
import sys

from agent_helpers import Lines, start
from launcher_helpers import ROOT
from namespaces import hosts, split_figure2
from recorded_systems import check_of_a_real_run

from iotad.machine import agent_secret, certificates
from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_reader import read_recording

PORT = 7616
ROGUE = r"""
import sys, time, zenoh
from iotad.machine import certificates
from iotad.node_host import credentials, wire
from iotad.node_host.transport import open_session
hub, stranger, own, tools = sys.argv[1:5]
ROGUE = wire.encode("ROGUE")
TARGETS = ["iota/split/scheduler/mdl_command", "iota/split/vision/req"]
seen = []
# the control reads with the tools' credentials (what 'iotad echo' on a host of the system would use)
control = open_session([], [hub], mode="client", connect_timeout=5, credentials=credentials.load(tools),
                       tls=certificates.host_files(own, "guest"))
control.declare_subscriber("iota/split/**", lambda s: seen.append(s.payload.to_bytes()))
time.sleep(1.0)
print("control OPENED, read", len(seen))
guessed = credentials.Credentials("node-scheduler", "guessed-password")
for name, files, given in (("tls without a certificate", None, False),
                           ("tls with another authority's", certificates.host_files(stranger, "rogue"), False),
                           ("tls with the system's and no credentials", certificates.host_files(own, "guest"), False),
                           ("tls with the system's and a guessed password", certificates.host_files(own, "guest"), guessed)):
    try:
        with open_session([], [hub], mode="client", connect_timeout=2, credentials=given, tls=files) as s:
            read = []
            s.declare_subscriber("iota/split/**", lambda sample: read.append(1))
            for _ in range(10):
                for key in TARGETS:
                    s.put(key, ROGUE)
                time.sleep(0.1)
            print(name, "OPENED, read", len(read))
    except zenoh.ZError:
        print(name, "refused")
time.sleep(0.5)
print("control saw a rogue sample:", ROGUE in seen)
control.close()
"""


def test_a_third_namespace_can_neither_command_nor_read_a_system_across_hosts(tmp_path):
    certs, other = tmp_path / "certs", tmp_path / "other"
    with hosts("brain", "arm", "rogue", net=206) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        certificates.init_authority(certs)
        for host, addresses in (("brain", [hub]), ("arm", [arm]), ("guest", [])):
            certificates.issue_host(certs, host, addresses)
            agent_secret.write(certs, host)  # as 'iotad certs host' does
        certificates.init_authority(other)
        certificates.issue_host(other, "rogue")
        path = tmp_path / "split.toml"
        path.write_text(split_figure2("split", hub, PORT, "brain", "arm", arm, "tls"))
        recording = tmp_path / "secure.mcap"
        agent = start(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                               "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs)))
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                             "--certs", str(certs), "-o", str(recording)))
        agent_lines, run_lines = Lines(agent), Lines(run)
        try:
            # the arm's engines start: the requester asks the scheduler while the rogue tries
            assert run_lines.wait_for("[arm] ", 90) and run_lines.wait_for("start gate open", 90), \
                run_lines.text()[-4000:]
            assert run_lines.wait_for("vision: live (on another host)", 60), run_lines.text()[-4000:]
            # the tools' file of this run, as 'iotad echo' on brain finds it (private to this user)
            tools = re.search(r"credentials in (\S+),", run_lines.text()).group(1) + "/iotad-tools.json"
            rogue = subprocess.run(net.exec("rogue", sys.executable, "-c", ROGUE, f"tls/{hub}:{PORT}",
                                            str(other), str(certs), tools),
                                   capture_output=True, text=True, timeout=60, cwd=ROOT)
        finally:
            code = interrupt_then_kill(run)
            interrupt_then_kill(agent)
        output, said = run_lines.text(), agent_lines.text()
        assert code == 130, output[-4000:]
        lines = rogue.stdout.splitlines()
        assert re.fullmatch(r"control OPENED, read [1-9]\d*", lines[0]), rogue.stdout + rogue.stderr
        assert lines[1:] == ["tls without a certificate refused", "tls with another authority's refused",
                             "tls with the system's and no credentials refused",
                             "tls with the system's and a guessed password refused",
                             "control saw a rogue sample: False"], rogue.stdout + rogue.stderr
        assert "access control: on (" in output and "access control is OFF" not in output, output[-4000:]
        assert "agent arm: ready at the hub (admitted as iotad-agent-arm)" in said, said
        assert "COMMIT" in output and "[arm]" in output, output[-4000:]
    data = read_recording(recording)
    assert not [m for m in data.messages if m.value == "ROGUE"]
    inputs = [e for e in data.trace("scheduler") if e["kind"] == "input"]
    assert inputs and all(e.get("value") != "ROGUE" for e in inputs)
    out = check_of_a_real_run(recording)
    assert re.search(r"vision: \d+ events, [1-9]\d* firings checked", out), out[-3000:]
