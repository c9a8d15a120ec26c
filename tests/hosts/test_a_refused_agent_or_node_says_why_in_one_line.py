"""Access control across hosts, on loopback: each host's agent secret comes from the system's
authority and is private; an agent keeps the credentials the hub sends it in a private folder for
the run and removes them after it; and a hub that does not admit an agent (a certificate of
another authority, a secret of another authority) or a node (credentials not the run's) is said
in one line naming the cause, never a traceback or a silent wait."""
import json
import os
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from agent_helpers import agent_lines, hub_session
from launcher_helpers import ROOT

from iotad.machine import agent_secret, certificates
from iotad.machine.certificates import CertificateError
from iotad.node_host.transport import free_port
from iotad.launcher.hosts.agent import Agent, AgentError


@pytest.fixture
def authority(tmp_path):
    certificates.init_authority(tmp_path / "ca")
    certificates.issue_host(tmp_path / "ca", "brain", ["127.0.0.1"])
    certificates.issue_host(tmp_path / "ca", "arm", ["127.0.0.1"])
    certificates.init_authority(tmp_path / "other")
    certificates.issue_host(tmp_path / "other", "arm", ["127.0.0.1"])
    return tmp_path / "ca"


def test_an_agent_secret_is_private_and_differs_by_host_and_authority(authority, tmp_path):
    written = agent_secret.write(authority, "arm")
    assert stat.S_IMODE(written.stat().st_mode) == 0o600
    assert agent_secret.read(authority, "arm") == agent_secret.derive(authority, "arm")
    assert agent_secret.derive(authority, "brain") != agent_secret.derive(authority, "arm")
    assert agent_secret.derive(tmp_path / "other", "arm") != agent_secret.derive(authority, "arm")
    # the hub without the authority's key reads the host's file instead, or says what is missing
    (tmp_path / "copy").mkdir()
    (tmp_path / "copy" / "arm.secret").write_text(written.read_text())
    assert agent_secret.derive(tmp_path / "copy", "arm") == agent_secret.derive(authority, "arm")
    with pytest.raises(CertificateError, match=r"no agent secret for host 'base'.*iotad certs secret base"):
        agent_secret.derive(tmp_path / "copy", "base")


FAKE_LAUNCHER = """#!{python}
import json, os, stat, sys
path = os.environ["IOTAD_CREDENTIALS"]
print(json.dumps({{"user": json.load(open(path))["user"], "folder": os.path.dirname(path),
                  "modes": sorted({{oct(stat.S_IMODE(os.stat(os.path.join(os.path.dirname(path), f)).st_mode))
                                   for f in os.listdir(os.path.dirname(path))}}),
                  "folder_mode": oct(stat.S_IMODE(os.stat(os.path.dirname(path)).st_mode)),
                  "files": sorted(os.listdir(os.path.dirname(path))),
                  "args": sys.argv[1:], "part": json.load(open(sys.argv[-1]))}}), flush=True)
"""


def test_an_agent_keeps_its_hosts_credentials_private_for_the_run_and_removes_them(tmp_path):
    fake = tmp_path / "python"
    fake.write_text(FAKE_LAUNCHER.format(python=sys.executable))
    fake.chmod(0o700)
    system = tmp_path / "split.toml"
    system.write_text("# the system file\n")
    lines = []
    agent = Agent("arm", ["tcp/127.0.0.1:1"], say=lines.append, python=str(fake), workdir=tmp_path / "work")
    published = []
    agent._publish = lambda part, payload: published.append((part, payload))  # no hub in this test
    # a node's password in an order (a hub from before the hosts' routers made their nodes' own)
    # is not written: only the launcher's is kept
    order = {"system": system.read_text(), "path": str(system), "run": {"no_record": True},
             "credentials": {"iotad-launcher-arm": "p1", "node-vision": "p2"}}
    # the agent spawns its runs on the thread of serve() (its parent-death signal's thread): here,
    # with no hub to serve, a thread of the test's takes that one spawn
    taker = threading.Thread(target=lambda: agent._spawns.get(timeout=30)(), daemon=True)
    taker.start()
    agent._start(order)
    taker.join(30)
    agent.child.wait(30)
    deadline = time.monotonic() + 30  # the relay thread publishes the exit once it has read every line
    while not any(part == "exit" for part, _ in published) and time.monotonic() < deadline:
        time.sleep(0.05)
    seen = json.loads(next(payload["line"] for part, payload in published if part == "log"))
    # a typed order, no command line: the host's part, with its launcher's options
    assert seen["user"] == "iotad-launcher-arm" and seen["args"][:2] == ["-m", "iotad.launcher.run.host_part"]
    assert seen["part"]["run"]["no_record"] is True and seen["part"]["run"]["host"] == "arm"
    assert seen["part"]["system"] == system.read_text() and "credentials" not in seen["part"]
    assert seen["folder_mode"] == "0o700" and seen["modes"] == ["0o600"]
    assert "iotad-launcher-arm.json" in seen["files"] and "node-vision.json" not in seen["files"], seen["files"]
    assert not Path(seen["folder"]).exists()  # removed once the run ended
    for bad, why in (({"node-vision": "p2"}, "lack this host's launcher"), ({"x": 1}, "map user names")):
        with pytest.raises(AgentError, match=why):
            agent._start({**order, "credentials": bad})


def test_an_agent_of_another_authority_or_with_a_wrong_secret_says_why_once(authority, tmp_path):
    port = free_port()
    agent_secret.write(authority, "arm")
    agent_secret.write(tmp_path / "other", "arm")
    wrong = tmp_path / "wrong-secret"
    wrong.mkdir()
    for name in ("ca.pem", "arm.pem", "arm.key"):
        (wrong / name).write_bytes((authority / name).read_bytes())
    (wrong / "arm.secret").write_text((tmp_path / "other" / "arm.secret").read_text())
    with hub_session(authority, port, {"iotad-agent-arm": agent_secret.derive(authority, "arm")}, tmp_path):
        for certs, cause in ((tmp_path / "other", "this host's certificates are not the system's"),
                             (wrong, "refused the credentials of user 'iotad-agent-arm'"),
                             (authority, "ready at the hub (admitted as iotad-agent-arm)")):
            lines, errors = agent_lines(certs, port, cause)
            assert [line for line in lines if cause in line], (certs, lines, errors)
            refusals = [line for line in lines if "not admitted" in line]
            assert len(refusals) <= 1 and "Traceback" not in errors, (lines, errors)  # said once


def test_a_node_whose_credentials_are_refused_says_so_in_one_line(authority, tmp_path):
    port = free_port()
    stale = tmp_path / "stale.json"
    stale.write_text(json.dumps({"user": "node-echo", "password": "not-this-run's"}))
    os.chmod(stale, 0o600)
    config = {"system": "t", "path": "echo", "source": {"kind": "python", "ref": f"{ROOT}/examples/echo.py:Echo"},
              "listen": [], "connect": [f"tls/127.0.0.1:{port}"]}
    env = {**os.environ, "IOTAD_CREDENTIALS": str(stale), certificates.ENV_DIR: str(authority),
           certificates.ENV_HOST: "arm"}
    with hub_session(authority, port, {"node-echo": "the run's"}, tmp_path):
        done = subprocess.run([sys.executable, "-m", "iotad.node_host", "--config-json", json.dumps(config)],
                              capture_output=True, text=True, timeout=60, cwd=ROOT, env=env)
    assert done.returncode == 2, done.stderr
    assert done.stderr.strip().splitlines() == [
        f"iotad.node_host: error: echo: cannot start on zenoh: not admitted: the hub at tls/127.0.0.1:{port} refused the "
        "credentials of user 'node-echo': they are not this run's (an agent's HOST.secret from another authority, or "
        "a stale credentials file)"]


def test_a_hub_that_cannot_admit_a_hosts_agent_refuses_to_start_in_one_line(authority, tmp_path):
    # the hub's folder has its own certificate but neither the authority's key nor arm's secret
    from namespaces import split_figure2

    hub_only = tmp_path / "hub-only"
    hub_only.mkdir()
    for name in ("ca.pem", "brain.pem", "brain.key"):
        (hub_only / name).write_bytes((authority / name).read_bytes())
    path = tmp_path / "split.toml"
    path.write_text(split_figure2("split", "127.0.0.1", free_port(), "brain", "arm", "127.0.0.1", "tls"))
    done = subprocess.run([sys.executable, "-m", "iotad", "run", str(path), "--certs", str(hub_only), "--no-record",
                           "--until", "5"], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert done.returncode == 2 and done.stdout == "", done.stdout + done.stderr
    assert done.stderr.strip().splitlines() == [
        f"iotad: error: no agent secret for host 'arm': {hub_only}/arm.secret is missing (nor the authority's key "
        f"{hub_only}/ca.key to derive it); make it with 'iotad certs secret arm --dir DIR' where the authority's "
        "key is, and copy it beside the host's key"]
    made = subprocess.run([sys.executable, "-m", "iotad", "certs", "secret", "arm", "--dir", str(authority)],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert made.returncode == 0 and agent_secret.read(authority, "arm") == agent_secret.derive(authority, "arm")
    (hub_only / "arm.secret").write_text((authority / "arm.secret").read_text())  # as the hub's copy
    refused = subprocess.run([sys.executable, "-m", "iotad", "certs", "secret", "arm", "--dir", str(hub_only)],
                             capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert refused.returncode == 2 and "no authority's key" in refused.stderr and "Traceback" not in refused.stderr
