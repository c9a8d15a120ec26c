"""Helpers for launcher tests: start `iotad run` as a process we own, find its children in /proc,
and watch a system's liveliness tokens and launcher events from an observer session."""
import itertools
import os
import queue
import random
import socket
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import zenoh

from iotad.node_host import wire
from iotad.node_host.transport import open_session
from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.recorder import CONNECT_RETRY

ROOT = Path(__file__).resolve().parents[1]
IOTAS = Path(__file__).resolve().parent / "system_iotas.py"


_outputs = itertools.count()  # one output file per launcher, even two started in the same instant


def _ephemeral_low() -> int:
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as ports:
            return int(ports.read().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port() -> int:
    """A free loopback port below the kernel's ephemeral range, for a hub that another process
    will listen on a moment later. `iotad.node_host.transport.free_port` returns an ephemeral port, which
    any outgoing connection (a node, a recorder, another test's peer) may take as its source
    port before the hub binds it; ports below the range are only ever taken by listeners."""
    low = _ephemeral_low()
    chooser = random.Random()
    for _ in range(200):
        port = chooser.randrange(max(1024, low - 12000), low)
        with socket.socket() as probe:
            try:
                probe.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError("no free loopback port below the ephemeral range")


def gone(pid: int) -> bool:
    """No such process, or a zombie (dead, waiting for a reaper)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except (FileNotFoundError, ProcessLookupError):
        return True


def children_of(pid: int) -> dict[int, str]:
    """Live direct children of `pid`: pid -> command line."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                fields = stat.read().rsplit(")", 1)[1].split()
            if int(fields[1]) != pid or fields[0] in ("Z", "X"):
                continue
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                found[int(entry)] = cmdline.read().replace(b"\0", b" ").decode(errors="replace")
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
    return found


def wait_until(condition, timeout: float, step: float = 0.02):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(step)
    return condition()


@contextmanager
def launcher(system_file: Path, *args: str, cwd: Path | None = None, prefix: tuple = (), secure: bool = False):
    """`iotad run SYSTEM ...` as a process of its own, stopped on the way out: SIGINT (a clean
    stop that removes what it made), then SIGKILL to its group if it has not ended in 15 s.
    Yields the Popen; its output (plain lines) goes to `<system_file>.N.out`, and its node
    configs and logs to `<system_file>.N.logs` (unless the args say --log-dir), never /tmp.
    Without `secure` it runs `--insecure`: an Observer opened before the hub has no credentials
    (tests of access control itself pass secure=True; docs/access-control.md)."""
    if not secure and "--insecure" not in args:
        args = (*args, "--insecure")
    number = next(_outputs)
    out = Path(str(system_file) + f".{number}.out")
    if "--log-dir" not in args:
        args = (*args, "--log-dir", str(system_file) + f".{number}.logs")
    with open(out, "wb") as sink:
        proc = subprocess.Popen([*prefix, sys.executable, "-m", "iotad", "run", str(system_file), "--plain", *args],
                                stdout=sink, stderr=subprocess.STDOUT, cwd=cwd or ROOT, start_new_session=True)
    proc.output = out
    try:
        yield proc
    finally:
        stop_launcher(proc)


def stop_launcher(proc: subprocess.Popen, patience: float = 15.0) -> None:
    if proc.poll() is not None:
        return
    kids = children_of(proc.pid)
    interrupt_then_kill(proc, patience)
    for pid in kids:  # the launcher (or the parent-death signal) should have done it; be sure
        if not gone(pid):
            os.kill(pid, signal.SIGKILL)


class Observer:
    """A zenoh session on a system: liveliness changes and @launcher events, with arrival times."""

    def __init__(self, system: str, hub: str):
        self.system = system
        # zenoh retries `connect` at 1 s doubling to 4 s: an observer made before its launcher's hub
        # listened linked seconds late on a loaded machine and missed the first @trace bursts (the
        # interpreter-restart test saw no mdl_command taken); every 100 ms, as a recorder does
        self.session = open_session(connect=[hub], extra=CONNECT_RETRY)
        self.alive: queue.Queue = queue.Queue()   # (monotonic, path, present)
        self.events: queue.Queue = queue.Queue()  # (monotonic, event dict)
        base = f"{wire.PREFIX}/{system}"
        self._subs = [
            self.session.liveliness().declare_subscriber(f"{base}/**/@alive", self._on_alive, history=True),
            self.session.declare_subscriber(wire.launcher_key(system), self._on_event),
        ]

    def _on_alive(self, sample) -> None:
        path = str(sample.key_expr)[len(f"{wire.PREFIX}/{self.system}/"):-len("/@alive")]
        self.alive.put((time.monotonic(), path, sample.kind == zenoh.SampleKind.PUT))

    def _on_event(self, sample) -> None:
        self.events.put((time.monotonic(), wire.decode(sample.payload.to_bytes())))

    def wait_alive(self, path: str, present: bool, timeout: float) -> float | None:
        """Monotonic time of the next change of `path` to `present`, or None after `timeout`."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                when, who, state = self.alive.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                return None
            if who == path and state == present:
                return when

    def wait_all_alive(self, paths, timeout: float) -> bool:
        """Whether every path in `paths` has shown a token within `timeout` (consumes changes)."""
        missing = set(paths)
        deadline = time.monotonic() + timeout
        while missing:
            try:
                _, who, state = self.alive.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                return False
            if state:
                missing.discard(who)
        return True

    def wait_event(self, predicate, timeout: float) -> dict | None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                _, event = self.events.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                return None
            if predicate(event):
                return event

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self.session.close()


def pair_system(tmp_path: Path, port: int, extra_system: str = "", extra_node: str = "") -> Path:
    """A source node and a sink node bound together, on the real node host."""
    path = tmp_path / "pair.toml"
    path.write_text(f"""
[system]
name = "pair"
{extra_system}
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]

[[node]]
name = "src"
python = "{IOTAS}:Source"
{extra_node}

[[node]]
name = "dst"
python = "{IOTAS}:Sink"
{extra_node}

[[bind]]
from = "src.out"
to = "dst.inp"
""")
    return path
