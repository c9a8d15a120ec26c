"""The `iotad` command line. Each subcommand lives in a module of `iotad.cli.commands` that defines
`register(subparsers)`; this file only discovers them, groups them for `iotad --help`, and turns
every failure into one line on stderr (`iotad: error: ...`, exit 2; Ctrl-C exits 130)."""
from __future__ import annotations

import argparse
import importlib
import math
import os
import pkgutil
import signal
import sys
import textwrap

from iotad import __version__
from iotad.launcher.run.recording_paths import drop_empty_claim, is_regular_file  # noqa: F401 - as commands know them

from . import commands

# `iotad --help` lists the commands in the order of the work: specify, run, record and examine,
# then watch a live system. A command module not named here is listed under "other".
GROUPS = (
    ("try it", ("demo", "new")),
    ("specify and simulate an IOTA (virtual time, one process)", ("spec",)),
    ("run a system (one process per IOTA, over zenoh), or sweep or stress it in virtual time",
     ("run", "agent", "certs", "sweep", "stress")),
    ("record and examine a recording (MCAP)", ("record", "info", "replay", "check", "plot", "export", "recover",
                                               "candump", "cat")),
    ("watch a running system", ("top", "view", "ls", "echo", "pub", "hz")),
    ("bring up a CAN bus", ("can",)),
)

EPILOG = """\
a first session, from the repository root:
  iotad demo --virtual                              the Figure 2 scheduler in virtual time
  iotad spec run nodes/scheduler/scheduler.iota --inputs examples/scheduler-inputs.jsonl --until 10
  iotad run examples/figure2.toml --until 20 -o recordings/fig2.mcap     over zenoh, recorded
  iotad check recordings/fig2.mcap                  did every node keep to its spec?

Run 'iotad COMMAND --help' for a command's options and examples; README.md has a tour.
Set IOTAD_DEBUG=1 to see the Python traceback of an unexpected error."""


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line: `iotad: error: ...`, exit 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        where = self.prog.removeprefix("iotad").strip()
        self.exit(2, f"iotad: error: {where + ': ' if where else ''}{message} "
                     f"(see '{self.prog} --help')\n")


# ---------------------------------------------------------------- argument types, shared by commands
def _number(text: str, kind: type, what: str, low: float | None, low_open: bool, allow_inf: bool = False):
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    if kind is float and (math.isnan(value) or (math.isinf(value) and not allow_inf)):
        said = "not a number" if math.isnan(value) else "infinite"
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r} ({said})")
    if low is not None and (value < low or (low_open and value == low)):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (durations, rates, periods)."""
    return _number(text, float, "a number > 0", 0.0, True)


def nonnegative_float(text: str) -> float:
    """A finite number >= 0 (tolerances, times to start at)."""
    return _number(text, float, "a number >= 0", 0.0, False)


def finite_float(text: str) -> float:
    return _number(text, float, "a finite number", None, False)


def positive_int(text: str) -> int:
    return _number(text, int, "a whole number > 0", 0, True)


def nonnegative_int(text: str) -> int:
    return _number(text, int, "a whole number >= 0", 0, False)


SEED_MAX = 2**64 - 1  # a recording keeps the seed in msgpack, whose integers end at 64 bits


def seed(text: str) -> int:
    """A random policy's seed: a whole number from 0 to 2**64 - 1."""
    value = _number(text, int, f"a whole number from 0 to {SEED_MAX}", 0, False)
    if value > SEED_MAX:
        raise argparse.ArgumentTypeError(f"expected a whole number from 0 to {SEED_MAX}, got {text!r}")
    return value


def port(text: str) -> int:
    """A TCP port, 0 (any free one) to 65535."""
    value = _number(text, int, "a port number 0-65535", 0, False)
    if value > 65535:
        raise argparse.ArgumentTypeError(f"expected a port number 0-65535, got {text!r}")
    return value


def endpoint(text: str) -> str:
    """A zenoh endpoint such as tcp/127.0.0.1:7447 (an argparse type)."""
    from iotad.node_host.transport import endpoint_problem
    problem = endpoint_problem(text)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return text


def byte_size(text: str) -> int:
    """`100M`, `1.5G`, `64K`, `4096`: bytes (K, M, G are 1024-based; a trailing B or iB is allowed)."""
    units = {"": 1, "K": 1024, "M": 1024 ** 2, "G": 1024 ** 3, "T": 1024 ** 4}
    body = text.strip().upper().removesuffix("IB").removesuffix("B")
    unit = body[-1:] if body[-1:] in units and body[-1:] else ""
    try:
        value = float(body[:-1] if unit else body)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a size such as 100M, 1.5G or 65536, got {text!r}") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"must be a finite size, got {text!r}")
    size = int(value * units[unit])
    if not size > 0:
        raise argparse.ArgumentTypeError(f"must be a positive size, got {text!r}")
    return size


def load_checked(path: str):
    """The system file at `path`, checked (`load_system`); a `CliError` listing every problem otherwise."""
    from iotad.launcher.system.system_file import SystemFileError, load_system

    try:
        return load_system(path)
    except SystemFileError as exc:
        raise CliError(str(exc) if len(exc.errors) == 1 else
                       f"{len(exc.errors)} problems in the system file:\n" + str(exc)) from None


def output_file(path: str, option: str = "-o") -> None:
    """Refuse, with one line, an output path that cannot be written: a folder, or one under a file."""
    from iotad.launcher.run.recording_paths import unwritable

    problem = unwritable(path)
    if problem:
        raise CliError(f"{option} {path}: {problem}")


def new_recording(path: str, force: bool, option: str = "-o") -> None:
    """Refuse, with one line, to write a recording over one that is already there, unless `force`."""
    from iotad.launcher.run.recording_paths import RecordingClaimError, new_recording as check

    try:
        check(path, force, option)
    except RecordingClaimError as exc:
        raise CliError(str(exc)) from None


def not_its_own_file(path: str, recording, option: str = "-o") -> None:
    """Refuse an output that is one of the files `recording` was read from (the file, or a
    member of its split set), even with --force: writing it would destroy what is being copied."""
    from pathlib import Path

    target = Path(path).resolve()
    for source in [recording.path, *getattr(recording, "files", [])]:
        if Path(source).resolve() == target:
            raise CliError(f"{option} {path}: is a file of the recording being read; name another file")


def claim_recording(path: str, force: bool, option: str = "-o") -> bool:
    """The recording's name claimed (`recording_paths.claim_recording`), or one line saying why not."""
    from iotad.launcher.run.recording_paths import RecordingClaimError, claim_recording as claim

    try:
        return claim(path, force, option)
    except RecordingClaimError as exc:
        raise CliError(str(exc)) from None


def key_expression(text: str) -> str:
    """A zenoh key expression: chunks separated by '/', none empty, no spaces or '#', '?', '$' misuse."""
    if not text or text.startswith("/") or text.endswith("/") or "//" in text or any(c in text for c in " #?"):
        raise argparse.ArgumentTypeError(f"not a key expression: {text!r} (chunks separated by '/', none empty, "
                                         "e.g. iota/figure2/scheduler/ack/0 or 'iota/figure2/**')")
    return text


# ---------------------------------------------------------------- the parser
def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="iotad", usage="iotad [-h] [--version] COMMAND [ARGS...]",
        description=textwrap.fill(
            "iotad: a runtime of Input-Output Timed Automata (IOTAs) for robot modules that share motors. "
            "Specify an IOTA (ESPRIT or Python), simulate it in virtual time, run a system of IOTAs as "
            "processes over zenoh, record it to MCAP, then replay and check the recording against the specs.", 78),
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"iotad {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", help=argparse.SUPPRESS, prog="iotad")
    modules = []
    for info in pkgutil.iter_modules(commands.__path__):
        modules.append(importlib.import_module(f"{commands.__name__}.{info.name}"))
    for module in sorted(modules, key=lambda m: (getattr(m, "ORDER", 50), m.__name__)):
        module.register(sub)
    parser.description += "\n\n" + _command_listing(sub)
    return parser


def _command_listing(sub: argparse._SubParsersAction) -> str:
    helps = {action.dest: action.help or "" for action in sub._choices_actions}
    listed = {name for _, names in GROUPS for name in names}
    groups = list(GROUPS) + [("other", tuple(n for n in helps if n not in listed))]
    lines = []
    width = max(map(len, helps)) + 2
    for title, names in groups:
        names = [n for n in names if n in helps]
        if not names:
            continue
        lines.append(f"{title}:")
        for name in names:
            wrapped = textwrap.wrap(helps[name], 78 - width - 2) or [""]
            lines.append(f"  {name:<{width}}{wrapped[0]}")
            lines.extend(" " * (width + 2) + more for more in wrapped[1:])
    return "\n".join(lines)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    # zenoh's errors end with the Rust source location (" at /root/.cargo/..."): not for users.
    text = text.split(" at /", 1)[0].split("\n", 1)[0]
    return text or type(exc).__name__


def main(argv: list[str] | None = None) -> int:
    if argv is None and signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        # started with SIGINT ignored (a background job of a non-interactive shell, a test run
        # started so): Python then installs no KeyboardInterrupt, and a command that waits would
        # never stop on Ctrl-C. Every iotad command stops on SIGINT, as `iotad run` does.
        signal.signal(signal.SIGINT, signal.default_int_handler)
    code = _main(argv)
    if argv is None:  # the program itself (`iotad`, `python -m iotad`), not a call from Python
        _leave_stray_threads(code)
    return code


def _leave_stray_threads(code: int) -> None:
    """Exit now if code we imported left threads that Python would wait for at exit. A command
    that builds nodes to check them (`run`, `check`, `replay`) runs their `init`, and one that
    starts a thread (not a daemon) would keep `iotad` from ever exiting."""
    import threading

    stray = [t.name for t in threading.enumerate()
             if t is not threading.main_thread() and not t.daemon and t.is_alive()]
    if not stray:
        return
    # zenoh runs Python callbacks on threads of its own ("pyo3-closure"); one still delivering a
    # sample as its session closes (seen on a loaded machine) is not node code: exit, quietly
    foreign = [name for name in stray if "pyo3-closure" not in name]
    if foreign:
        print(f"iotad: note: not waiting for {len(foreign)} thread(s) that a node's code started "
              f"({', '.join(foreign[:3])}{', ...' if len(foreign) > 3 else ''})", file=sys.stderr)
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()  # imports every command: a Ctrl-C may come in the middle
    except KeyboardInterrupt:
        print("", file=sys.stderr)
        return 130
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a usage error already printed
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    from iotad.recording.mcap_format import RecordingError
    try:
        return int(args.func(args) or 0)
    except (CliError, RecordingError) as exc:  # bad input, a damaged recording among it
        print(f"iotad: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # `iotad spec run ... | head`: the reader left; say nothing, and keep Python from
        # complaining about the closed stdout at exit.
        try:
            sys.stdout = open(os.devnull, "w")  # noqa: SIM115
        except OSError:
            pass
        return 0
    except OSError as exc:  # a file we were told to write or read, at a place that says no
        if os.environ.get("IOTAD_DEBUG"):
            raise
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"iotad: error: {where}{exc.strerror or _first_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001 - a bug or an unforeseen input: still one line
        if os.environ.get("IOTAD_DEBUG"):
            raise
        module = type(exc).__module__
        if module.startswith("zenoh"):
            print(f"iotad: error: zenoh: {_first_line(exc)}", file=sys.stderr)
            return 2
        print(f"iotad: error: unexpected {type(exc).__name__}: {_first_line(exc)} "
              f"(IOTAD_DEBUG=1 shows the traceback; please report it)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    # Run as `python -m iotad.cli`, this module is `__main__`, whose CliError is not the one the
    # commands raise: delegate to the imported module so errors stay one line.
    from iotad.cli import main as imported_main
    sys.exit(imported_main())
