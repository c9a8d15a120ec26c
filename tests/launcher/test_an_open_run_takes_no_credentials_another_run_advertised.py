"""A run under access control advertises its tools' credentials for its hub's port (a pointer in
a private folder of this user), so that `iotad ls` and friends started by hand find them. An open
run on the same port (another network namespace, or after a run killed before it could take its
pointer back) must not pick them up: its hub has no users, and refuses a session that shows a
password. Its launcher tells its nodes and recorder "no credentials" (`IOTAD_CREDENTIALS` set
but empty), and a pointer whose launcher is gone is ignored by everyone."""
import subprocess
import sys

from launcher_helpers import ROOT, free_port, pair_system
from iotad.node_host import credentials as creds
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.system.system_file import load_system
from iotad.recording.mcap_reader import read_recording


def pointer_of(port: int):
    return creds.pointer_path(creds.user_dir(), port)


def dead_pid() -> int:
    done = subprocess.Popen(["true"])
    done.wait()
    return done.pid


def test_a_pointer_left_by_a_launcher_that_is_gone_is_ignored(monkeypatch):
    monkeypatch.delenv(creds.ENV, raising=False)
    port = free_port()
    store = creds.CredentialStore(["iotad-tools"])
    try:
        store.advertise([f"tcp/127.0.0.1:{port}"], "iotad-tools")
        assert creds.for_endpoints([f"tcp/127.0.0.1:{port}"]).user == "iotad-tools"  # its launcher: this process
        tools = store.file_of("iotad-tools")
        pointer_of(port).write_text(f"{tools}\n{dead_pid()}\n")  # as a killed launcher leaves it
        assert creds.for_endpoints([f"tcp/127.0.0.1:{port}"]) is None
        pointer_of(port).write_text(f"{tools}\n")  # written before pointers named their launcher
        assert creds.for_endpoints([f"tcp/127.0.0.1:{port}"]).user == "iotad-tools"
    finally:
        store.remove()
    assert not pointer_of(port).exists()


def test_credentials_set_but_empty_mean_none_and_no_looking(monkeypatch, tmp_path):
    port = free_port()
    store = creds.CredentialStore(["iotad-tools"])
    try:
        store.advertise([f"tcp/127.0.0.1:{port}"], "iotad-tools")
        monkeypatch.setenv(creds.ENV, "")
        assert creds.for_endpoints([f"tcp/127.0.0.1:{port}"]) is None
        # what an open run's launcher hands its nodes and recorder
        open_run = AccessControl.off(load_system(pair_system(tmp_path, port)), "--insecure")
        assert open_run.node_env("dst")[creds.ENV] == "" and open_run.recorder_env()[creds.ENV] == ""
    finally:
        store.remove()


def test_an_open_run_records_on_a_port_another_run_advertised_credentials_for(tmp_path, monkeypatch):
    monkeypatch.delenv(creds.ENV, raising=False)
    port = free_port()
    store = creds.CredentialStore(["iotad-tools"])  # the other run's, its launcher alive (this process)
    try:
        store.advertise([f"tcp/127.0.0.1:{port}"], "iotad-tools")
        system = pair_system(tmp_path, port)
        done = subprocess.run([sys.executable, "-m", "iotad", "run", str(system), "--insecure", "--plain",
                               "--until", "3", "--after-live", "-o", str(tmp_path / "open.mcap"),
                               "--log-dir", str(tmp_path / "logs")],
                              capture_output=True, text=True, timeout=120, cwd=ROOT)
    finally:
        store.remove()
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    messages = read_recording(tmp_path / "open.mcap").messages
    sent = [m for m in messages if m.topic == "iota/pair/src/out"]
    taken = [m for m in messages if m.topic == "iota/pair/dst/@trace" and isinstance(m.value, dict)
             and m.value.get("kind") == "input"]
    # the source sends once a second: each of its outputs taken, but for one in flight at the stop
    assert len(sent) >= 2 and len(taken) >= len(sent) - 1, (done.stdout[-2000:], len(sent), len(taken))
