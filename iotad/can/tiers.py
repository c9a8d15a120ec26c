"""A command run with a CAN bus, in the best tier this host has: vcan, user-mode Linux, udp_multicast.

1. `vcan`: the kernel has CAN; vcan0 is made in a private network namespace (`unshare -rn`).
2. `uml`: the kernel has no CAN (these machines); Debian's user-mode Linux kernel boots in ~2 s
   with the host's root through hostfs, loads can, can-raw, can-dev and vcan, makes vcan0, runs
   the command (same files, working directory and environment; one vCPU) and powers off.
3. `udp_multicast`: an IP multicast group on the loopback of a private network namespace.

The command learns its bus from the environment: IOTAD_CAN_TIER, IOTAD_CAN_INTERFACE
(socketcan | udp_multicast) and IOTAD_CAN_CHANNEL (vcan0 | the group); `iotad.can.bus.open_env_bus()`
opens it. IOTAD_CAN_TIER set before choosing forces a tier.

    python -m iotad.can.tiers                       # which tiers this host has, and the best
    python -m iotad.can.tiers run -- candump-like-command args...
    python -m iotad.can.tiers run --tier uml --timeout 60 -- .venv/bin/python script.py

Every process started here has an owner that stops it: each run is its own process group,
killed on time-out or interruption; the user-mode kernel's console is kept for error messages.
"""
from __future__ import annotations

import argparse
import functools
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from .bus import ENV_CHANNEL, ENV_INTERFACE, ENV_TIER, UDP_GROUP

TIERS = ("vcan", "uml", "udp_multicast")
UML_KERNEL = Path("/usr/bin/linux.uml")
UML_MODULES = Path("/usr/lib/uml/modules")
CAN_MODULES = ("net/can/can.ko", "net/can/can-raw.ko", "drivers/net/can/dev/can-dev.ko", "drivers/net/can/vcan.ko")
PROBE_TIMEOUT = 10.0

_VCAN_SETUP = "ip link set lo up && ip link add dev vcan0 type vcan && ip link set up vcan0"
_UDP_SETUP = "ip link set lo up && ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo"


@dataclass(frozen=True)
class Tier:
    name: str          # vcan | uml | udp_multicast
    interface: str     # what python-can opens inside: socketcan | udp_multicast
    channel: str       # vcan0 | the multicast group
    description: str

    def environment(self) -> dict[str, str]:
        return {ENV_TIER: self.name, ENV_INTERFACE: self.interface, ENV_CHANNEL: self.channel}


def tier(name: str) -> Tier:
    if name == "vcan":
        return Tier("vcan", "socketcan", "vcan0", "vcan0 of this kernel in a private network namespace")
    if name == "uml":
        return Tier("uml", "socketcan", "vcan0", f"vcan0 in user-mode Linux {_uml_version() or '?'} (1 vCPU)")
    if name == "udp_multicast":
        return Tier("udp_multicast", "udp_multicast", UDP_GROUP,
                    f"udp_multicast group {UDP_GROUP} on the loopback of a private network namespace")
    raise TierUnavailable(f"unknown CAN tier {name!r}; tiers: {', '.join(TIERS)}")


class TierUnavailable(RuntimeError):
    """No tier, or not the one asked for, can run here; the message says why."""


class TierTimeout(RuntimeError):
    """The command ran past its time-out and was killed; `.run` holds what it printed."""

    def __init__(self, message: str, run: "TierRun"):
        super().__init__(message)
        self.run = run


@dataclass
class TierRun:
    tier: Tier
    command: list[str]
    returncode: int
    output: str                    # the command's stdout and stderr, interleaved
    seconds: float
    console: str = ""              # the user-mode kernel's own messages (boot, shutdown)

    def check(self) -> "TierRun":
        """Itself, or RuntimeError with the tier, the exit status and the output's tail."""
        if self.returncode != 0:
            raise RuntimeError(f"{shlex.join(self.command)} exited {self.returncode} in tier {self.tier.name}"
                               f"\n--- output (tail) ---\n{self.output[-4000:]}"
                               + (f"\n--- console (tail) ---\n{self.console[-2000:]}" if self.console else ""))
        return self


# ------------------------------------------------------------------ which tiers this host has

@functools.cache
def why_not(name: str) -> str | None:
    """None if tier `name` can run here, else the reason it cannot."""
    if name == "vcan":
        return _probe_netns(_VCAN_SETUP, "this kernel has no vcan (CAN) support")
    if name == "uml":
        if not UML_KERNEL.exists():
            return (f"{UML_KERNEL} is missing: `apt-get install -y user-mode-linux kmod` "
                    f"(as root; `make test` does it where it can)")
        if not shutil.which("insmod") and not shutil.which("kmod"):
            return "insmod is missing: `apt-get install -y kmod`"
        version = _uml_version()
        if not version or not all((UML_MODULES / version / "kernel" / m).exists() for m in CAN_MODULES):
            return f"the user-mode kernel's CAN modules are missing under {UML_MODULES}/{version or '<version>'}"
        return _probe_uml()
    if name == "udp_multicast":
        return _probe_netns(_UDP_SETUP, "cannot make a private network namespace with multicast on loopback")
    return f"unknown tier {name!r}"


def available() -> dict[str, str | None]:
    """Every tier and why it cannot run here (None: it can)."""
    return {name: why_not(name) for name in TIERS}


def best_tier(prefer: str | None = None) -> Tier:
    """The tier asked for (argument, else IOTAD_CAN_TIER), else the best this host has."""
    wanted = prefer or os.environ.get(ENV_TIER) or None
    if wanted:
        reason = why_not(wanted) if wanted in TIERS else f"unknown tier (tiers: {', '.join(TIERS)})"
        if reason:
            raise TierUnavailable(f"CAN tier {wanted!r} cannot run here: {reason}")
        return tier(wanted)
    for name in TIERS:
        if why_not(name) is None:
            return tier(name)
    raise TierUnavailable("no CAN tier can run here: " + "; ".join(f"{n}: {r}" for n, r in available().items()))


def _probe_netns(setup: str, meaning: str) -> str | None:
    if not shutil.which("unshare") or not shutil.which("ip"):
        return "`unshare` or `ip` is missing (util-linux, iproute2)"
    try:
        done = subprocess.run(["unshare", "-rn", "sh", "-c", setup], capture_output=True, text=True,
                              timeout=PROBE_TIMEOUT)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"unshare -rn failed: {exc}"
    if done.returncode == 0:
        return None
    error = (done.stderr or done.stdout).strip().splitlines()
    detail = error[-1] if error else f"exit {done.returncode}"
    if "unshare" in detail:
        return f"no private network namespace (unshare -rn: {detail})"
    return f"{meaning} ({detail})"


UML_PROBE_TIMEOUT = 60.0  # a boot takes ~2 s; a loaded machine (a test suite) may take far longer
UML_BOOT_TIMEOUT = 120.0  # s from the kernel's start to the command's, not counted in a run's timeout


def _probe_uml() -> str | None:
    """None if user-mode Linux boots here and makes vcan0, else what went wrong. Its files being
    installed is not enough: on a host CPU with a large extended register state (AMX), Debian's
    6.1 user-mode kernel panics at its first process ("ptrace set fp regs failed")."""
    try:
        _run_uml(tier("uml"), ["true"], UML_PROBE_TIMEOUT, "/", {}, None, "256M").check()
    except TierTimeout:
        return f"user-mode Linux did not boot within {UML_PROBE_TIMEOUT:g} s"
    except (TierUnavailable, RuntimeError, OSError) as exc:
        lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
        # the cause, where the console names one, before the panic it leads to
        for word in ("ptrace", "iotad-can init", "panic", "did not report"):
            telling = [line for line in lines if word in line]
            if telling:
                return f"user-mode Linux does not boot on this host ({telling[0]})"
        return f"user-mode Linux does not boot on this host ({lines[0] if lines else 'no output'})"
    return None


@functools.cache
def _uml_version() -> str | None:
    if not UML_KERNEL.exists():
        return None
    try:
        done = subprocess.run([str(UML_KERNEL), "--version"], capture_output=True, text=True, timeout=PROBE_TIMEOUT)
        version = done.stdout.strip().splitlines()[0] if done.stdout.strip() else ""
    except (OSError, subprocess.TimeoutExpired, IndexError):
        version = ""
    if version and (UML_MODULES / version).is_dir():
        return version
    found = sorted(p.name for p in UML_MODULES.glob("*") if p.is_dir()) if UML_MODULES.is_dir() else []
    return found[-1] if found else (version or None)


# ------------------------------------------------------------------ running a command

def run(command: list[str], tier_name: str | None = None, *, timeout: float = 120.0, cwd: str | None = None,
        env: dict[str, str] | None = None, stream=None, uml_memory: str = "1G") -> TierRun:
    """Run `command` with a CAN bus in tier `tier_name` (default: the best). Its output comes back in
    `TierRun.output` (and is copied to `stream`, a text file, as it comes). TierTimeout after
    `timeout` seconds of the command (user-mode Linux's boot not counted), the command and
    everything it started killed."""
    if not command:
        raise ValueError("no command to run")
    chosen = best_tier(tier_name)
    environment = dict(os.environ if env is None else env)
    environment.update(chosen.environment())
    environment.setdefault("PYTHONUNBUFFERED", "1")
    cwd = str(Path(cwd or os.getcwd()).resolve())
    if chosen.name == "uml":
        return _run_uml(chosen, list(command), timeout, cwd, environment, stream, uml_memory)
    setup = _VCAN_SETUP if chosen.name == "vcan" else _UDP_SETUP
    argv = ["unshare", "-rn", "sh", "-c", f'{setup} && exec "$@"', "iotad-can", *command]
    return _run_process(chosen, list(command), argv, timeout, cwd, environment, stream)


STOP_GRACE = 20.0  # seconds a stopped command gets for its own stop (the launcher: 3 + 2 s, then its recorder)


class Terminated(BaseException):
    """SIGTERM to the wrapper (`main`), raised where it waits so that the command is stopped as
    for Ctrl-C: with the signal passed on, not killed."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop_gently(process: subprocess.Popen, signum: int) -> None:
    """Pass `signum` on to the command's process group, as a terminal's Ctrl-C reaches every
    process of its foreground group (a script's `subprocess.call` kills its child if only it is
    told), and give it STOP_GRACE seconds to stop by itself (a launcher stops its nodes and
    finishes its recording); a second Ctrl-C is passed on too."""
    deadline = time.monotonic() + STOP_GRACE
    while process.poll() is None and time.monotonic() < deadline:
        try:
            os.killpg(process.pid, signum)  # its own session: the group is the command's
            process.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            break
        except (KeyboardInterrupt, Terminated) as again:  # a second signal: the command hurries
            signum = getattr(again, "signum", signal.SIGINT)
        except ProcessLookupError:
            break


def _run_process(chosen: Tier, command, argv, timeout, cwd, environment, stream, console_of=None,
                 forward_signals: bool = True, begins: str | None = None) -> TierRun:
    """`argv` run until it ends, or killed `timeout` s after it began: after its start, or, given
    `begins`, after the line that starts with it (user-mode Linux's boot, 2 s here and far longer
    on a loaded machine, is not the command's time; UML_BOOT_TIMEOUT bounds it)."""
    started = time.monotonic()
    lines: list[str] = []
    began = threading.Event()
    process = subprocess.Popen(argv, cwd=cwd, env=environment, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, start_new_session=True)
    reader = threading.Thread(target=_pump, args=(process.stdout, lines, stream, begins, began), daemon=True)
    reader.start()
    try:
        if begins is not None:
            _wait_until_begun(process, began, started + UML_BOOT_TIMEOUT)
        returncode = process.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(process)
        reader.join(timeout=5)
        run_ = TierRun(chosen, command, -9, "".join(lines), time.monotonic() - started)
        if console_of:
            run_.output, run_.console, _ = console_of(run_.output)
        what = f"ran past {timeout:g} s" if begins is None or began.is_set() else \
            f"did not begin within {UML_BOOT_TIMEOUT:g} s of the kernel's start"
        raise TierTimeout(f"{shlex.join(command)} {what} in tier {chosen.name} and was killed"
                          f"\n--- output (tail) ---\n{run_.output[-3000:]}"
                          + (f"\n--- console (tail) ---\n{run_.console[-2000:]}" if run_.console else ""), run_)
    except BaseException as exc:
        signum = signal.SIGINT if isinstance(exc, KeyboardInterrupt) else getattr(exc, "signum", None)
        if signum is not None and forward_signals:
            _stop_gently(process, signum)  # Ctrl-C or SIGTERM: the command's own stop, then the rest
            reader.join(timeout=5)         # its last lines (a launcher's summary) reach the stream
        _kill_group(process)  # interrupted (Ctrl-C, a test's failure): nothing is left running
        raise
    finally:
        if process.poll() is None:
            _kill_group(process)
    _kill_group(process)  # what the command left running in its group goes with it
    reader.join(timeout=5)
    return TierRun(chosen, command, returncode, "".join(lines), time.monotonic() - started)


def _wait_until_begun(process: subprocess.Popen, began: threading.Event, deadline: float) -> None:
    """Until the command began (or the process ended before it did); TimeoutExpired past `deadline`."""
    while not began.wait(0.05):
        if process.poll() is not None:
            return
        if time.monotonic() > deadline:
            raise subprocess.TimeoutExpired(process.args, UML_BOOT_TIMEOUT)


def _pump(pipe, lines: list[str], stream, begins: str | None = None, began: threading.Event | None = None) -> None:
    for raw in iter(pipe.readline, b""):
        line = raw.decode("utf-8", "replace").replace("\r\n", "\n").replace("\r", "")
        lines.append(line)
        if begins is not None and line.startswith(begins):
            began.set()
        if stream is not None:
            try:
                stream.write(line)
                stream.flush()
            except (OSError, ValueError):
                stream = None
    pipe.close()


def _kill_group(process: subprocess.Popen) -> None:
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        pass


# ------------------------------------------------------------------ user-mode Linux

_BEGIN, _END = "=== iotad-can command begins ===", "=== iotad-can command ended ==="


def _uml_init(workdir: Path, command: list[str], cwd: str, environment: dict[str, str], version: str) -> str:
    exports = "\n".join(f"export {name}={shlex.quote(value)}" for name, value in sorted(environment.items())
                        if name.isidentifier() and "\n" not in value and name not in ("PWD", "OLDPWD", "SHLVL"))
    modules = " ".join(f"{UML_MODULES / version / 'kernel' / m}" for m in CAN_MODULES)
    status = workdir / "status"
    return f"""#!/bin/sh
# init of a user-mode Linux that runs one command with vcan0, then powers off (iotad.can.tiers)
export PATH=/usr/sbin:/usr/bin:/sbin:/bin
fail() {{ echo "iotad-can init: $*"; echo 125 > {status}; sync; echo o > /proc/sysrq-trigger; poweroff -f; }}
mount -t proc proc /proc || fail "cannot mount /proc"
mount -t sysfs sysfs /sys
mkdir -p /dev/shm && mount -t tmpfs -o mode=1777 tmpfs /dev/shm || fail "cannot mount /dev/shm"
mkdir -p /dev/pts && mount -t devpts devpts /dev/pts
ip link set lo up || fail "cannot raise lo"
for module in {modules}; do insmod "$module" || fail "insmod $module failed"; done
ip link add dev vcan0 type vcan && ip link set up vcan0 || fail "cannot make vcan0"
{exports}
cd {shlex.quote(cwd)} || fail "cannot enter {cwd}"
echo "{_BEGIN}"
{shlex.join(command)} < /dev/null
echo $? > {status}.tmp
echo "{_END}"
mv {status}.tmp {status}
sync
echo o > /proc/sysrq-trigger
poweroff -f
"""


def _split_console(text: str) -> tuple[str, str, bool]:
    """(command output, kernel console, whether the command ran) from the UML console text."""
    if _BEGIN not in text:
        return "", text, False
    head, rest = text.split(_BEGIN, 1)
    rest = rest[1:] if rest.startswith("\n") else rest
    output, _, tail = rest.partition(_END)
    return output, head + tail, True


class _ConsoleFilter:
    """Copies only the command's part of the console to a stream, as it comes."""

    def __init__(self, stream):
        self.stream, self.inside = stream, False

    def write(self, line: str) -> None:
        if line.startswith(_BEGIN):
            self.inside = True
        elif line.startswith(_END):
            self.inside = False
        elif self.inside:
            self.stream.write(line)

    def flush(self) -> None:
        self.stream.flush()


def _run_uml(chosen: Tier, command, timeout, cwd, environment, stream, memory) -> TierRun:
    version = _uml_version()
    workdir = Path(tempfile.mkdtemp(prefix="iotad-uml-"))
    try:
        init = workdir / "init.sh"
        init.write_text(_uml_init(workdir, command, cwd, environment, version))
        init.chmod(0o755)
        argv = [str(UML_KERNEL), f"mem={memory}", "root=/dev/root", "rootfstype=hostfs", "rootflags=/", "rw",
                f"init={init}", f"uml_dir={workdir}", "umid=iotad-can", "quiet", "con=null", "con0=fd:0,fd:1"]
        # UML backs its memory with an unlinked file in TMPDIR: on tmpfs it is fast and leaves nothing
        shm = Path("/dev/shm")
        memory_dir = shm if shm.is_dir() and os.access(shm, os.W_OK) else workdir
        uml_env = {"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "TMPDIR": str(memory_dir)}
        try:
            # a signal to the user-mode kernel would end it at once: the command is killed instead
            run_ = _run_process(chosen, command, argv, timeout, cwd, uml_env,
                                None if stream is None else _ConsoleFilter(stream), console_of=_split_console,
                                forward_signals=False, begins=_BEGIN)
        except TierTimeout:
            raise
        output, console, ran = _split_console(run_.output)
        status = workdir / "status"
        if not status.exists():
            raise TierUnavailable(
                f"user-mode Linux did not report the command's exit status (kernel exit {run_.returncode}, "
                f"command {'started' if ran else 'never started'})\n--- console ---\n{console[-3000:]}"
                + (f"\n--- output ---\n{output[-2000:]}" if output else ""))
        code = int(status.read_text().strip() or 125)
        if code == 125 and not ran:
            raise TierUnavailable(f"user-mode Linux could not set up vcan0\n--- console ---\n{console[-3000:]}")
        return TierRun(chosen, command, code, output, run_.seconds, console)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


# ------------------------------------------------------------------ for tests and benchmarks

class TierBus:
    """A CAN bus in one tier, for tests (the `can_bus` fixture) and benchmarks: runs commands and
    Python scripts that open it with `iotad.can.bus.open_env_bus()`."""

    def __init__(self, tier_name: str | None = None):
        self.tier = best_tier(tier_name)
        self.name, self.interface, self.channel = self.tier.name, self.tier.interface, self.tier.channel

    def describe(self) -> str:
        return f"{self.name}: {self.tier.description}"

    def run(self, command: list[str], *, timeout: float = 60.0, cwd: str | None = None,
            env: dict[str, str] | None = None, stream=None) -> TierRun:
        return run(command, self.name, timeout=timeout, cwd=cwd, env=env, stream=stream)

    def run_python(self, source: str, *args: str, timeout: float = 60.0, cwd: str | None = None,
                   env: dict[str, str] | None = None, stream=None) -> TierRun:
        """Run Python `source` (a script's text) with this bus; sys.argv[1:] are `args`."""
        with tempfile.NamedTemporaryFile("w", suffix=".py", prefix="iotad-can-", dir="/tmp", delete=False) as file:
            file.write(source)
        try:
            return self.run([sys.executable, file.name, *args], timeout=timeout, cwd=cwd, env=env, stream=stream)
        finally:
            os.unlink(file.name)

    def __repr__(self) -> str:
        return f"<TierBus {self.describe()}>"


# ------------------------------------------------------------------ command line

def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m iotad.can.tiers",
        description="Run a command with a CAN bus (vcan0, or a udp_multicast group) in the best tier this "
                    "host has; without `run`, say which tiers it has. The command finds its bus in "
                    "IOTAD_CAN_INTERFACE and IOTAD_CAN_CHANNEL (iotad.can.bus.open_env_bus).",
        usage="python -m iotad.can.tiers [detect | run [--tier T] [--timeout S] -- COMMAND...]",
        epilog="example: python -m iotad.can.tiers run -- .venv/bin/python bench/can_bus.py")
    parser.add_argument("action", nargs="?", choices=("run", "detect"), default="detect")
    parser.add_argument("--tier", choices=TIERS, help="use this tier (default: IOTAD_CAN_TIER, else the best)")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds before the command is killed (600)")
    argv = list(sys.argv[1:] if argv is None else argv)
    command = argv[argv.index("--") + 1:] if "--" in argv else []
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    if args.action == "detect":
        if command:
            parser.error("a command needs `run`: python -m iotad.can.tiers run -- CMD...")
        for name, reason in available().items():
            print(f"{name:14} {'available' if reason is None else 'unavailable: ' + reason}")
        try:
            chosen = best_tier(args.tier)
        except TierUnavailable as exc:
            print(f"best: none ({exc})")
            return 1
        print(f"best: {chosen.name} ({chosen.description})")
        return 0
    if not command:
        parser.error("no command: python -m iotad.can.tiers run -- CMD...")

    def terminated(signum, frame):
        raise Terminated(signum)

    signal.signal(signal.SIGTERM, terminated)  # passed on to the command, as Ctrl-C is
    # Ctrl-C as KeyboardInterrupt even for a wrapper started with SIGINT ignored (Python then
    # leaves it ignored): a background job of a non-interactive shell, as a test run or CI may be,
    # would otherwise never pass a SIGINT on, and its command would run to its end
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        chosen = best_tier(args.tier)
        print(f"iotad-can: tier {chosen.name}: {chosen.description}", file=sys.stderr, flush=True)
        result = run(command, chosen.name, timeout=args.timeout, stream=sys.stdout)
    except (TierUnavailable, TierTimeout) as exc:
        print(f"iotad-can: {exc}", file=sys.stderr)
        return 124 if isinstance(exc, TierTimeout) else 125
    except KeyboardInterrupt:
        return 130
    except Terminated:
        return 143
    return result.returncode


if __name__ == "__main__":
    sys.exit(main())
