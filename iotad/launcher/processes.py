"""Owning OS processes: spawn one (never fork in Python), stop it in escalating steps, restart it
by policy. Knows nothing of zenoh or IOTAs; the launcher drives it.

Every child runs in its own session and process group (so a Ctrl-C at the terminal reaches only
the launcher, which then stops its children in order) and dies with the launcher even when the
launcher is killed with SIGKILL: a tiny exec wrapper sets the Linux parent-death signal with
prctl(PR_SET_PDEATHSIG) and then execs the real command, keeping the pid. The wrapper is its own
interpreter started by subprocess (fork+exec in C), so no Python code runs in a forked copy of a
process that holds zenoh threads. PR_SET_PDEATHSIG fires when the *thread* that spawned the child
ends, so spawn from a thread that lives as long as the launcher (its main thread).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

# argv: ppid, death signal, command... . If the parent died before prctl took effect, getppid()
# has changed: exit rather than run an orphan. Without prctl (not Linux) just exec.
# An ignored signal stays ignored across exec, and a launcher started from a script's background
# job (`iotad run ... &`, nohup) inherits SIGINT ignored: give the child the default disposition
# of the signals that stop it, or a child without its own handlers would shrug off SIGINT.
_DEATH_WRAPPER = """
import os, signal, sys
expected_parent, death_signal = int(sys.argv[1]), int(sys.argv[2])
for stop_signal in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
    signal.signal(stop_signal, signal.SIG_DFL)
try:
    import ctypes
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(1, death_signal, 0, 0, 0) != 0:  # 1 = PR_SET_PDEATHSIG
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG)")
except (OSError, AttributeError):
    pass
if os.getppid() != expected_parent:
    os._exit(70)
os.execv(sys.argv[3], sys.argv[3:])
"""

FAILED_TO_START = 127


def wrapped_argv(argv: Sequence[str], death_signal: int = signal.SIGKILL) -> list[str]:
    """`argv` run under the parent-death wrapper (argv[0] must be an absolute executable path)."""
    if not sys.platform.startswith("linux"):
        return list(argv)
    return [sys.executable, "-I", "-c", _DEATH_WRAPPER, str(os.getpid()), str(int(death_signal)), *argv]


class Child:
    """One OS process we own: started with `start`, stopped with `stop`, always reaped.

    A waiter thread (owned here, ends when the process does) reports the exit at once through
    `on_exit(child, code)`, so supervision does not depend on polling."""

    def __init__(self, name: str, argv: Sequence[str], *, log: Path | None = None, cwd: str | None = None,
                 env: dict[str, str] | None = None, on_exit: Callable[["Child", int], None] | None = None,
                 death_signal: int = signal.SIGKILL):
        self.name, self.argv, self.log, self.cwd = name, list(argv), log, cwd
        self.death_signal = death_signal  # what the child gets if this process dies (kill -9)
        self.env = env
        self.on_exit = on_exit
        self.proc: subprocess.Popen | None = None
        self.started_at = 0.0       # time.monotonic() of the last start
        self.log_start = 0          # where the last start's output begins in `log` (it is appended to)
        self.code: int | None = None  # exit status of the last run (negative: killed by signal)
        self.last_signal: int | None = None  # the last signal sent to the current run (how it was stopped)
        self._waiter: threading.Thread | None = None

    @property
    def pid(self) -> int | None:
        return self.proc.pid if self.proc is not None else None

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def start(self) -> int:
        if self.running():
            raise RuntimeError(f"{self.name} is already running")
        env = dict(os.environ if self.env is None else self.env)
        env.setdefault("PYTHONUNBUFFERED", "1")
        out = open(self.log, "ab") if self.log is not None else subprocess.DEVNULL
        self.log_start = out.tell() if out is not subprocess.DEVNULL else 0
        try:
            self.proc = subprocess.Popen(wrapped_argv(self.argv, self.death_signal), stdin=subprocess.DEVNULL,
                                         stdout=out, stderr=subprocess.STDOUT, cwd=self.cwd, env=env,
                                         start_new_session=True, close_fds=True)
        finally:
            if out is not subprocess.DEVNULL:
                out.close()  # the child has its own copy
        self.code = None
        self.last_signal = None
        self.started_at = time.monotonic()
        proc = self.proc
        self._waiter = threading.Thread(target=self._wait, args=(proc,), name=f"wait-{self.name}", daemon=True)
        self._waiter.start()
        return proc.pid

    def _wait(self, proc: subprocess.Popen) -> None:
        code = proc.wait()
        # what it started and left behind (its own session: the group still bears its pid, which
        # Linux does not reuse while the group has members) ends with it
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        if proc is self.proc:
            self.code = code
        if self.on_exit is not None:
            self.on_exit(self, code)

    def signal(self, signum: int) -> None:
        """Signal the child's whole process group (its own session), if it still runs."""
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        self.last_signal = signum
        try:
            os.killpg(proc.pid, signum)
        except (ProcessLookupError, PermissionError):
            pass

    def wait(self, timeout: float) -> bool:
        """True once the process has exited (within `timeout` seconds)."""
        if self.proc is None:
            return True
        try:
            self.proc.wait(timeout=max(0.0, timeout))
            return True
        except subprocess.TimeoutExpired:
            return False

    def stop(self, interrupt_timeout: float = 3.0, terminate_timeout: float = 2.0) -> int | None:
        """SIGINT, then SIGTERM, then SIGKILL, each after its time-out; returns the exit status."""
        stop_all([self], interrupt_timeout, terminate_timeout)
        return self.code if self.proc is None else self.proc.returncode


def stop_all(children: Sequence[Child], interrupt_timeout: float = 3.0, terminate_timeout: float = 2.0,
             hurry: threading.Event | None = None) -> None:
    """Stop children together: SIGINT to all, wait; SIGTERM to the rest, wait; SIGKILL, reap.
    Once `hurry` is set (a second Ctrl-C), what is left of the SIGINT and SIGTERM waits is skipped
    (`hurry`: anything with `is_set()`, a threading.Event or a signal handler's Flag)."""
    steps = ((signal.SIGINT, interrupt_timeout), (signal.SIGTERM, terminate_timeout), (signal.SIGKILL, 5.0))
    for signum, timeout in steps:
        alive = [c for c in children if c.running()]
        if not alive:
            return
        for child in alive:
            child.signal(signum)
        deadline = time.monotonic() + timeout
        for child in alive:
            if hurry is None or signum == signal.SIGKILL:
                child.wait(deadline - time.monotonic())
                continue
            while not hurry.is_set() and not child.wait(min(0.05, deadline - time.monotonic())):
                if time.monotonic() >= deadline:
                    break


def interrupt_then_kill(proc: subprocess.Popen, patience: float = 15.0) -> int:
    """Stop a process started with `start_new_session=True` (an `iotad run` a tool or bench
    started): SIGINT, its clean stop; SIGKILL to its whole group if it has not ended within
    `patience` s. Returns its exit status."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(patience)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    return proc.wait()


@dataclass
class RestartPolicy:
    """When to start a node again after it exits, and how long to wait first.

    never: not again. on-failure: when it exited non-zero or was killed. always: whatever the
    status. The wait is `backoff * 2**k` (at most `backoff_max`), where k counts the restarts since
    the node last ran `healthy_after` seconds; at most `max_restarts` restarts in all."""

    mode: str = "on-failure"
    max_restarts: int = 5
    backoff: float = 0.1
    backoff_max: float = 10.0
    healthy_after: float = 10.0

    def wants_restart(self, code: int, restarts: int) -> bool:
        if self.mode == "never" or restarts >= self.max_restarts:
            return False
        return self.mode == "always" or code != 0

    def delay(self, consecutive: int) -> float:
        return min(self.backoff_max, self.backoff * (2 ** consecutive))


def log_tail(child: Child | None, lines: int = 4) -> str:
    """The last lines of a child's output since it last started (its stderr, where errors go;
    the log holds every start's, one after the other), for a report: one indented line each."""
    log = None if child is None else child.log
    if log is None:
        return ""
    try:
        with open(log, "rb") as stream:
            # a chatty log may be huge; an earlier start's lines are not this one's
            stream.seek(max(child.log_start, stream.seek(0, os.SEEK_END) - 4096))
            text = stream.read().decode(errors="replace").strip().splitlines()[-lines:]
    except OSError:
        return ""
    return "".join(f"\n    | {line}" for line in text)


def describe_exit(code: int | None) -> str:
    if code is None:
        return "running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    if code in (128 + signal.SIGTERM, 128 + signal.SIGINT):  # a node host stopped by that signal
        return f"exit {code} ({signal.Signals(code - 128).name})"
    return f"exit {code}"
