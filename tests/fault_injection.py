"""Faults made real in namespace hosts (tests/namespaces.py): a host's link to the hub cut and
healed, slowed with `tc tbf`, a process of a run found by its role in a host's namespace, stopped
with SIGSTOP or killed with SIGKILL; and the processes left in a run's namespaces afterwards. Each
action returns the wall-clock ns just before it took effect, for readings of the recordings."""
from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path


def processes_in(namespace: str) -> dict[int, list[str]]:
    """pid -> command line of every process in the network namespace `namespace`."""
    done = subprocess.run(["ip", "netns", "pids", namespace], capture_output=True, text=True, timeout=10)
    found = {}
    for word in done.stdout.split():
        try:
            argv = Path(f"/proc/{int(word)}/cmdline").read_bytes().split(b"\0")
        except (OSError, ValueError):
            continue  # gone meanwhile
        found[int(word)] = [part.decode(errors="replace") for part in argv if part]
    return found


def role_of(argv: list[str]) -> str | None:
    """What a process of a run is, by its command line: `node:NAME` (a node host, named by its
    config file NAME.json), `recorder`, `launcher` (a host's part, its agent's child), `agent`,
    `hub` (the hub's `iotad run`); None for anything else (`ip netns exec` itself, a shell)."""
    if "iotad.node_host" in argv:
        config = argv[argv.index("iotad.node_host") + 1] if argv.index("iotad.node_host") + 1 < len(argv) else ""
        return "node:" + Path(config).name.removesuffix(".json")
    if "iotad.recording.recorder_process" in argv:
        return "recorder"
    if "iotad.launcher.run.host_part" in argv:
        return "launcher"
    if "iotad" in argv and "agent" in argv:
        return "agent"
    if "iotad" in argv and "run" in argv:
        return "hub"
    return None


class Injector:
    """Faults in `net` (a namespaces.Hosts whose first host, `hub_host`, is joined to each other);
    `close()` heals and unshapes every link it touched and continues every process it stopped."""

    def __init__(self, net, hub_host: str = "brain"):
        self.net, self.hub_host = net, hub_host
        self._switches: dict[str, subprocess.Popen] = {}
        self._cut: set[str] = set()
        self._shaped: set[str] = set()
        self._stopped: set[int] = set()

    # ------------------------------------------------------------------ links
    def cut(self, host: str) -> int:
        return self._switch(host, "down")

    def heal(self, host: str) -> int:
        return self._switch(host, "up")

    def _switch(self, host: str, state: str) -> int:
        # one `ip -batch` process per link, started before it is needed, takes each line as it
        # comes: the link changes within a fraction of a millisecond of the time taken, not after
        # a process start (tens of ms on a loaded machine), which would count against time to safe
        name, namespace = self.net.links[(self.hub_host, host)]
        switch = self._switches.get(host)
        if switch is None:
            switch = self._switches[host] = subprocess.Popen(["ip", "-n", namespace, "-batch", "-"], text=True,
                                                            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                                            stderr=subprocess.DEVNULL)
        now = time.time_ns()
        switch.stdin.write(f"link set {name} {state}\n")
        switch.stdin.flush()
        (self._cut.add if state == "down" else self._cut.discard)(host)
        return now

    def slow(self, host: str, rate: str) -> int:
        """Both ends of the link between the hub's host and `host` shaped by a token bucket of
        `rate` (2 kB at once; a packet that would wait past 50 ms is dropped)."""
        now = time.time_ns()
        for a, b in ((self.hub_host, host), (host, self.hub_host)):
            self._tc(a, b, "add", "tbf", "rate", rate, "burst", "2kb", "latency", "50ms")
        self._shaped.add(host)
        return now

    def unslow(self, host: str) -> int:
        now = time.time_ns()
        for a, b in ((self.hub_host, host), (host, self.hub_host)):
            self._tc(a, b, "del")
        self._shaped.discard(host)
        return now

    def _tc(self, a: str, b: str, action: str, *qdisc: str) -> None:
        name, namespace = self.net.links[(a, b)]
        done = subprocess.run(["ip", "netns", "exec", namespace, "tc", "qdisc", action, "dev", name, "root", *qdisc],
                              capture_output=True, text=True, timeout=10)
        if done.returncode and action == "add":
            raise RuntimeError(f"cannot shape the link {a}-{b} (tc qdisc add ... tbf: {done.stderr.strip()})")

    # ------------------------------------------------------------------ processes
    def find(self, host: str, role: str) -> int | None:
        """The pid of the process of `role` (`node:NAME`, `recorder`, `launcher`, `agent`, `hub`) in
        `host`'s namespace; the oldest one if several (a recorder's restart), None if none."""
        found = [pid for pid, argv in processes_in(self.net.names[host]).items() if role_of(argv) == role]
        return min(found) if found else None

    def kill(self, pid: int) -> int:
        now = time.time_ns()
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        return now

    def stop(self, pid: int) -> int:
        now = time.time_ns()
        self._stopped.add(pid)
        try:
            os.kill(pid, signal.SIGSTOP)
        except ProcessLookupError:
            pass
        return now

    def cont(self, pid: int) -> int:
        now = time.time_ns()
        self._stopped.discard(pid)
        try:
            os.kill(pid, signal.SIGCONT)
        except ProcessLookupError:
            pass
        return now

    def close(self) -> None:
        """Every stopped process continued, every link unshaped and up: the run can stop cleanly."""
        for pid in list(self._stopped):
            self.cont(pid)
        for host in list(self._shaped):
            self.unslow(host)
        for host in list(self._cut):
            self.heal(host)
        for switch in self._switches.values():
            if switch.poll() is None:
                switch.stdin.close()
                try:
                    switch.wait(5)
                except subprocess.TimeoutExpired:
                    switch.kill()
                    switch.wait()


def leftovers(net) -> dict[str, dict[int, list[str]]]:
    """The processes still in each of `net`'s namespaces (host -> pid -> command line)."""
    return {host: found for host, namespace in net.names.items() if (found := processes_in(namespace))}


def kill_leftovers(net, patience: float = 10.0) -> dict[str, dict[int, list[str]]]:
    """Waits up to `patience` s for `net`'s namespaces to empty; what is still there then (the
    orphans, returned) is killed, so that no process outlives the run's namespaces."""
    deadline = time.monotonic() + patience
    while (found := leftovers(net)) and time.monotonic() < deadline:
        time.sleep(0.2)
    for processes in found.values():
        for pid in processes:
            try:
                os.kill(pid, signal.SIGCONT)
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    return found
