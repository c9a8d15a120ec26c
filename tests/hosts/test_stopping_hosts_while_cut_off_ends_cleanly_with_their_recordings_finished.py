"""Stopping a host's launcher while its host is cut off from the hub, and then the hub's launcher
while the cut lasts, ends each cleanly: Ctrl-C's exit status (130), every node stopped by its
SIGINT (none killed), the summary printed, each host's recording finished and accepted by `iotad
check`, and nothing but one line where zenoh could not reach the other side; never a traceback.

Before the fix, the cut-off host's launcher ended on `iotad: error: zenoh: close operation timed
out!` with exit status 2 and no summary, after killing its node, whose own session close had
outlasted its stop patience: zenoh closes a link to a cut-off peer with SO_LINGER 10 s and gives
up on the whole close after 10 s (iotad/node_host/session_close.py). One `iotad run --host` per
network namespace, each with `-o`, as tests/hosts/test_a_host_cut_off_from_the_hub_keeps_recording.py."""
import re
import subprocess
import sys
import time

from cut_recording import source_to_sink
from launcher_helpers import ROOT, children_of, gone, launcher, wait_until
from namespaces import hosts

PORT = 7662
CUT_BEFORE_STOP = 2.0  # s: well inside zenoh's lease, while the links to the other host are still open


def check(recording) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "iotad", "check", str(recording), "--no-delivery"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)


def ended_cleanly(output: str, host: str, node: str) -> None:
    assert "Traceback" not in output and "iotad: error" not in output, output[-3000:]
    assert f"{node}: stopped (exit 0)" in output, output[-3000:]  # its SIGINT stopped it: not killed
    assert f"summary of cut (host {host}):" in output, output[-3000:]
    zenoh_lines = [line for line in output.splitlines() if line.startswith("zenoh:")]
    assert len(zenoh_lines) <= 1, zenoh_lines


def test_stopping_hosts_while_cut_off_ends_cleanly_with_their_recordings_finished(tmp_path):
    hub_file, arm_file = tmp_path / "cut.mcap", tmp_path / "cut.arm.mcap"
    with hosts("brain", "arm", net=212) as net:
        path = tmp_path / "cut.toml"
        path.write_text(source_to_sink(net.addresses[("brain", "arm")], net.addresses["arm"], PORT))
        with launcher(path, "--host", "brain", "--until", "60", "-o", str(hub_file),
                      prefix=tuple(net.exec("brain"))) as brain:
            assert wait_until(lambda: "hub: " in brain.output.read_text(), 60), brain.output.read_text()[-3000:]
            with launcher(path, "--host", "arm", "--until", "60", "-o", str(arm_file),
                          prefix=tuple(net.exec("arm"))) as arm:
                assert wait_until(lambda: re.search(r"recording to [\s\S]*start gate open", arm.output.read_text()),
                                  60), arm.output.read_text()[-3000:]
                time.sleep(1.5)  # the source has fired, and both hosts' recorders heard it
                arm_nodes = children_of(arm.pid)
                net.cut("brain", "arm")
                try:
                    time.sleep(CUT_BEFORE_STOP)
                    arm.send_signal(2)  # Ctrl-C on the host that is cut off
                    arm_code = arm.wait(60)
                    brain_nodes = children_of(brain.pid)
                    brain.send_signal(2)  # ... and on the hub's, the cut still on
                    brain_code = brain.wait(60)
                finally:
                    net.heal("brain", "arm")
    arm_output, brain_output = arm.output.read_text(), brain.output.read_text()
    assert arm_code == 130, arm_output[-3000:]
    assert brain_code == 130, brain_output[-3000:]
    ended_cleanly(arm_output, "arm", "source")
    ended_cleanly(brain_output, "brain", "sink")
    assert arm_nodes and brain_nodes
    assert all(gone(pid) for pid in [*arm_nodes, *brain_nodes]), (arm_nodes, brain_nodes)
    for recording in (arm_file, hub_file):  # each host's recording finished and readable
        checked = check(recording)
        assert checked.returncode == 0, checked.stdout[-2000:] + checked.stderr[-2000:]
        assert "every node conforms to its spec" in checked.stdout, checked.stdout[-2000:]
