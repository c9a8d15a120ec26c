"""Helpers for tests of hosts' agents on loopback: a hub session under user-password
authentication over TLS, and `iotad agent` run until it says a given line."""
from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

from launcher_helpers import ROOT

from iotad.machine import certificates
from iotad.node_host.credentials import Credentials, CredentialStore
from iotad.node_host.transport import open_session
from iotad.launcher.processes import interrupt_then_kill


def hub_session(authority: Path, port: int, users: dict[str, str], tmp_path: Path):
    """A hub under user-password authentication that knows `users`, on tls/127.0.0.1:port."""
    store = CredentialStore([], parent=str(tmp_path), passwords=users)
    for user in users:  # the dictionary is what the hub checks against
        assert user in store.dictionary.read_text()
    hub = Credentials("iotad-hub", store.hub().password, str(store.dictionary))
    return open_session([f"tls/127.0.0.1:{port}"], [], credentials=hub,
                        tls=certificates.host_files(authority, "brain"))


class AgentProcess:
    """`iotad agent --name arm` on loopback with the certificates in `certs`; its lines as they come."""

    def __init__(self, certs: Path, port: int):
        self.proc = subprocess.Popen([sys.executable, "-m", "iotad", "agent", "--name", "arm", "--connect",
                                      f"tls/127.0.0.1:{port}", "--certs", str(certs)], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, cwd=ROOT, start_new_session=True)
        self.lines: list[str] = []
        self.changed = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self.changed:
                self.lines.append(line.rstrip("\n"))
                self.changed.notify_all()

    def wait_for(self, text: str, timeout: float = 40, after: int = 0) -> int:
        """The index of the first line from `after` on that holds `text` (-1: none within `timeout`)."""
        def found() -> int:
            return next((k for k in range(after, len(self.lines)) if text in self.lines[k]), -1)

        with self.changed:
            self.changed.wait_for(lambda: found() >= 0 or self.proc.poll() is not None, timeout)
            return found()

    def stop(self) -> str:
        """Stop it (SIGINT, then SIGKILL); its standard error."""
        interrupt_then_kill(self.proc)
        return self.proc.stderr.read()


class Lines:
    """A process's output, read as it comes: `wait_for(text)` returns once a line holds `text`."""

    def __init__(self, proc: subprocess.Popen):
        self.proc, self.lines, self.changed = proc, [], threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self.changed:
                self.lines.append(line)
                self.changed.notify_all()
        with self.changed:
            self.lines.append(None)  # the end
            self.changed.notify_all()

    def wait_for(self, text: str, timeout: float) -> bool:
        with self.changed:
            return self.changed.wait_for(lambda: any(line is None or text in line for line in self.lines)
                                         , timeout) and any(line and text in line for line in self.lines)

    def text(self) -> str:
        with self.changed:
            return "".join(line for line in self.lines if line)


def start(command: list[str], **options) -> subprocess.Popen:
    """`command` in a session of its own, its output (stdout and stderr together) to be read."""
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                            start_new_session=True, **options)


def agent_lines(certs: Path, port: int, until: str, timeout: float = 40) -> tuple[list[str], str]:
    """`iotad agent --name arm` until one of its lines holds `until` (or `timeout`): its lines and
    its standard error."""
    agent = AgentProcess(certs, port)
    try:
        agent.wait_for(until, timeout)
    finally:
        errors = agent.stop()
    return agent.lines, errors


def authority_for(certs: Path, hosts: dict[str, list[str]]) -> Path:
    """A system's authority in `certs` with a certificate and an agent secret for each host of
    `hosts` (name: its addresses), as 'iotad certs init' and 'iotad certs host' make them."""
    from iotad.machine import agent_secret

    certificates.init_authority(certs)
    for host, addresses in hosts.items():
        certificates.issue_host(certs, host, addresses)
        agent_secret.write(certs, host)
    return certs
