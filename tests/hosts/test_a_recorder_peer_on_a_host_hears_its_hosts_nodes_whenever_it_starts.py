"""An `iotad record` peer started by hand on a host of an open run (`--connect` the hub, `--listen`
on the host's address: gossip meshes it with every node) hears that host's nodes, and the other
host's, whether it starts before the run, while it starts, or after every node is live.

It used to hear none of them now and then (a loaded suite, several runs at once). A run under
access control advertises its tools' credentials for its hub's port, for tools started by hand;
a recorder, like any tool, took the credentials advertised for the port it connects to. A port
number alone names no hub: a guarded run in another network namespace (another test's "host", on
the same port) made the recorder show a password to this open hub, which refused it ("UsrPwd
extension - Recv InitSyn. Decoding error", at zenoh's debug level) at every retry, for the whole
run. The pointer now names its hub's network namespace too.

Here the other guarded run is this test process itself, in the machine's own namespace, having
advertised tools' credentials for the same port, as such a run does."""
import subprocess
import sys

import pytest

from launcher_helpers import ROOT, wait_until
from namespaces import agent, hosts, hosts_header

from iotad.launcher.processes import interrupt_then_kill
from iotad.node_host import credentials as creds
from iotad.recording.mcap_reader import RecordingError, read_recording

IOTAS = ROOT / "tests" / "system_iotas.py"
PORT, NET = 7677, 220
NODES = ("tick", "beat", "beat2")  # tick on brain, the others on arm


def system_text(hub: str, arm: str) -> str:
    text = hosts_header("peer", hub, PORT, "brain", "arm", arm)
    for name in NODES:
        text += (f'\n[[node]]\nname = "{name}"\nhost = "{"brain" if name == "tick" else "arm"}"\n'
                 f'python = "{IOTAS}:Pulse"\nparams = {{ period = 0.1 }}\n')
    return text


def heard(path) -> dict[str, int]:
    """Trace events of each node in the peer's recording so far."""
    try:
        messages = read_recording(path, salvage=True).messages
    except (RecordingError, OSError, ValueError):
        return {}
    return {name: sum(1 for m in messages if m.topic == f"iota/peer/{name}/@trace") for name in NODES}


@pytest.mark.parametrize("when", ["before", "while", "after"])
def test_a_recorder_peer_on_a_host_hears_its_hosts_nodes(tmp_path, monkeypatch, when):
    monkeypatch.delenv(creds.ENV, raising=False)
    other = creds.CredentialStore(["iotad-tools"])  # a guarded run's, alive, on the same port elsewhere
    peer = tmp_path / "peer.mcap"
    procs = {}
    try:
        other.advertise([f"tls/127.0.0.1:{PORT}"], "iotad-tools")
        with hosts("brain", "arm", net=NET) as net:
            hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
            path = tmp_path / "peer.toml"
            path.write_text(system_text(hub, arm))
            record = net.exec("arm", sys.executable, "-m", "iotad", "record", "iota/peer/**", "--connect",
                              f"tcp/{hub}:{PORT}", "--listen", f"tcp/{arm}:0", "-o", str(peer), "--quiet")
            log = tmp_path / "run.log"

            def start_recorder() -> None:
                procs["recorder"] = subprocess.Popen(record, cwd=ROOT, stdout=subprocess.DEVNULL,
                                                     stderr=(tmp_path / "recorder.err").open("w"),
                                                     start_new_session=True)

            with agent(net, "arm", f"tcp/{hub}:{PORT}"), log.open("w") as out:
                if when == "before":
                    start_recorder()
                procs["run"] = subprocess.Popen(
                    net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure", "--plain",
                             "--until", "120", "-o", str(tmp_path / "peer-run.mcap")),
                    stdout=out, stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True)
                if when == "while":
                    assert wait_until(lambda: "host arm: its agent runs its nodes" in log.read_text(), 60), \
                        log.read_text()[-3000:]
                    start_recorder()
                assert wait_until(lambda: log.read_text().count("start gate open") == 2, 90), log.read_text()[-3000:]
                if when == "after":
                    start_recorder()
                # every node's events reach it (before the fix: none, all run long)
                assert wait_until(lambda: all(heard(peer).get(name) for name in NODES), 30), \
                    (heard(peer), (tmp_path / "recorder.err").read_text()[-2000:])
                codes = {role: interrupt_then_kill(proc) for role, proc in procs.items()}
    finally:
        for proc in procs.values():
            interrupt_then_kill(proc)
        other.remove()
    assert codes == {"recorder": 0, "run": 130} or codes == {"run": 130, "recorder": 0}, codes
    counts = heard(peer)
    assert all(counts[name] > 0 for name in NODES), counts
