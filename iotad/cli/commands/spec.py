"""`iotad spec check|run|show`: the ESPRIT language from the command line."""
from __future__ import annotations

import argparse
import json
import sys

from iotad.cli import nonnegative_float, seed

ORDER = 10

DESCRIPTION = """\
Work with one ESPRIT specification (.iota, the language of the paper's Figure 2; see
docs/esprit.md) without zenoh or processes: check it, show its interface, or run it in
virtual time and print its timed trace."""

EPILOG = """\
examples:
  iotad spec check nodes/scheduler/scheduler.iota
  iotad spec show nodes/scheduler/scheduler.iota
  iotad spec run nodes/scheduler/scheduler.iota --param T=0.5 \\
      --inputs examples/scheduler-inputs.jsonl --until 10

Times (--until, script "t", windows) are in the spec's own time units; a system file maps
one unit to seconds (time_unit). See also: 'iotad run' (a system of processes),
'iotad check --spec' (does a recorded node implement this spec?)."""

RUN_EPILOG = """\
output: one JSON object per event, in firing order (docs/design.md section 5):
  {"t": 1.0, "iota": "scheduler", "action": "ack", "index": 0, "kind": "output", "value": "ABORT"}
kind is input, output, internal or violation; index is null for a plain channel; enum values
are names; structs are objects. A violation's value is {"violation": CODE, "message": TEXT}.

input script (--inputs): one JSON object a line, times not going backwards:
  {"t": 0.0, "action": "req", "index": 0, "value": {"control": {"w": 0.2, "k": 1.0},
   "epoch": 3.0, "timeout": 1.0, "priority": 1}}

examples:
  iotad spec run nodes/scheduler/scheduler.iota --param T=0.5 \\
      --inputs examples/scheduler-inputs.jsonl --until 10
  iotad spec run SPEC.iota --until 100 --policy random --seed 7 | grep violation"""


def register(sub: argparse._SubParsersAction) -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = sub.add_parser("spec", help="check, show or run an ESPRIT spec (.iota) in virtual time",
                            description=DESCRIPTION, epilog=EPILOG, formatter_class=formatter)
    commands = parser.add_subparsers(dest="spec_command", metavar="SUBCOMMAND")

    check = commands.add_parser(
        "check", help="parse and check a spec; list errors and warnings (exit 2 on errors)",
        description="Parse a spec and run the static checks (names, types, windows, reachability); print "
                    "each error and warning as file:line:col with the line and a caret. Exit 0 when there is "
                    "no error (warnings allowed), 2 otherwise.",
        epilog="example: iotad spec check nodes/scheduler/scheduler.iota\n"
               "see also: iotad spec show (the interface), iotad run --check (a whole system file)",
        formatter_class=formatter)
    check.add_argument("file", metavar="FILE.iota", help="an ESPRIT spec")
    check.set_defaults(func=cmd_check)

    run = commands.add_parser(
        "run", help="run a spec in virtual time; print its trace as JSONL",
        description="Instantiate one IOTA of the file, feed it the input script (if any) and run it in "
                    "virtual time from 0 to --until (spec time units); print every event as one JSON line "
                    "on stdout. Same spec, inputs, policy and seed: the same trace.",
        epilog=RUN_EPILOG, formatter_class=formatter)
    run.add_argument("file", metavar="FILE.iota", help="an ESPRIT spec")
    run.add_argument("--until", type=nonnegative_float, required=True, metavar="T",
                     help="virtual time to run to, in spec time units (required)")
    run.add_argument("--iota", metavar="NAME", help="which IOTA of the file (default: the last one)")
    run.add_argument("--param", action="append", default=[], metavar="K=V",
                     help="set a parameter (repeatable); V is JSON (N=3, T=0.5, on=true) or an enum member")
    run.add_argument("--inputs", metavar="SCRIPT.jsonl",
                     help='input script: one {"t", "action", "index", "value"} object a line (default: no inputs)')
    run.add_argument("--policy", choices=("eager", "latest", "random"), default="eager",
                     help="eager: fire at the earliest allowed time (default); latest: at the latest; "
                          "random: anywhere in the window")
    run.add_argument("--seed", type=seed, default=0, metavar="S", help="seed of the random policy (default 0)")
    run.set_defaults(func=cmd_run)

    show = commands.add_parser(
        "show", help="print the interface of a spec's IOTAs as a table",
        description="Print each IOTA's parameters and channels: name, direction, value type and switching "
                    "time (spec time units).",
        epilog="example: iotad spec show nodes/scheduler/scheduler.iota --iota scheduler", formatter_class=formatter)
    show.add_argument("file", metavar="FILE.iota", help="an ESPRIT spec")
    show.add_argument("--iota", metavar="NAME", help="which IOTA of the file (default: all)")
    show.set_defaults(func=cmd_show)
    parser.set_defaults(func=lambda args: parser.print_help() or 0)


def _fail(message: str) -> int:
    """An error of the spec (`file:line:col: message`, the line and a caret): the first line
    gets the `iotad: error:` prefix every command uses; the caret lines stay, they show where."""
    print(message if message.startswith("iotad: error:") else f"iotad: error: {message}", file=sys.stderr)
    return 2


def _read(path: str, what: str = "") -> str | None:
    """The text of a file, or None after one error line (missing, a folder, not text)."""
    import os

    from iotad.kernel.text_file import read_text_file

    label = f"{what} {path}" if what else path
    problem = None
    if os.path.isdir(path):
        problem = "is a directory"
    elif not os.path.exists(path):
        problem = "no such file"
    else:
        try:
            return read_text_file(path)
        except UnicodeDecodeError:
            problem = "not UTF-8 text (a binary file?)"
        except OSError as exc:
            problem = exc.strerror or str(exc)
    print(f"iotad: error: cannot read {label}: {problem}", file=sys.stderr)
    return None


def _hint(path: str) -> str:
    """A hint when the file does not look like an ESPRIT spec at all."""
    from pathlib import Path

    suffix = Path(path).suffix
    if suffix == ".py":
        return f"\n  hint: {path} is Python; Python IOTAs run with 'iotad run' (python = \"file.py:Class\")"
    if suffix in (".toml", ".mcap", ".json", ".jsonl"):
        return f"\n  hint: {path} is not an ESPRIT spec (.iota)"
    return ""


def _load(path: str):
    """The ESPRIT module of `path`, or None after the error (with the caret) is printed."""
    from iotad.esprit import EspritError, load_text

    text = _read(path)
    if text is None:
        return None
    try:
        module = load_text(text, path)
    except EspritError as exc:
        _fail(str(exc) + _hint(path))
        return None
    if not module.iotas:
        _fail(f"{path}: the file declares no iota" + _hint(path))
        return None
    return module


def cmd_check(args: argparse.Namespace) -> int:
    from iotad.esprit import check_text

    text = _read(args.file)
    if text is None:
        return 2
    if not text.strip():
        return _fail(f"{args.file}: the file is empty: no iota to check")
    errors, warnings = check_text(text, args.file)
    for diagnostic in errors + warnings:
        print(diagnostic, file=sys.stderr)
    if errors:
        print(f"iotad: error: {args.file}: {len(errors)} error(s), {len(warnings)} warning(s)"
              + _hint(args.file), file=sys.stderr)
        return 2
    from iotad.esprit import load_text
    module = load_text(text, args.file)
    if not module.iotas:  # as `spec show` and `spec run` say
        return _fail(f"{args.file}: the file declares no iota (only comments, types or constants)")
    unbuildable = _unbuildable(module)
    # an IOTA without parameters is built one way only: if that fails, nothing can build it
    never = {name: why for name, why in unbuildable.items() if not getattr(module.iotas[name], "params", True)}
    for name, why in unbuildable.items():
        if name in never:
            print(f"{args.file}: error: iota {name} cannot be built ({why}), and it has no parameters that "
                  f"could change that", file=sys.stderr)
        else:
            print(f"{args.file}: warning: iota {name} cannot be built with its default parameters ({why}): "
                  f"a system file must give it others", file=sys.stderr)
    if never:
        print(f"iotad: error: {args.file}: {len(never)} iota(s) that nothing can build" + _hint(args.file),
              file=sys.stderr)
        return 2
    print(f"{args.file}: ok ({len(warnings) + len(unbuildable)} warning(s))")
    return 0


def _unbuildable(module) -> dict[str, str]:
    """The IOTAs of a checked file that its default parameters do not build (an array of -3
    members, say), each with why: what `spec run` and a system file without params would hit."""
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine

    found = {}
    for name, factory in module.iotas.items():
        try:
            Engine(factory(None), VirtualClock(), record=False)  # the engine builds the action instances
        except Exception as exc:  # noqa: BLE001 - whatever building raises is the finding
            found[name] = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return found


def _param_value(text: str):
    """A --param value: JSON when it parses (3, 2.5, true, "x"), else the bare word (an enum member)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text
    except ValueError:  # json reads no int of more than 4300 digits
        from iotad.cli import CliError
        from iotad.kernel.types import HUGE_INT

        raise CliError(f"--param value of {len(text)} characters: an integer {HUGE_INT}") from None


def cmd_run(args: argparse.Namespace) -> int:
    from iotad.kernel import trace_jsonl as trace
    from iotad.esprit import EspritError
    from iotad.kernel.policy import make_policy
    from iotad.kernel.input_script import ScriptError, parse_script, run_script

    params = {}
    for item in args.param:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            return _fail(f"--param {item!r}: expected NAME=VALUE")
        if key.strip() in params:
            return _fail(f"--param {key.strip()} is given twice")
        params[key.strip()] = _param_value(value.strip())
    inputs = []
    if args.inputs:
        text = _read(args.inputs, "input script")
        if text is None:
            return 2
        try:
            inputs = parse_script(text.splitlines(), args.inputs)
        except ScriptError as exc:
            return _fail(str(exc))
    module = _load(args.file)
    if module is None:
        return 2
    try:
        root = module.factory(args.iota)(None, **params)
    except EspritError as exc:
        return _fail(str(exc))
    out = sys.stdout

    def emit(event: dict) -> None:
        out.write(trace.dumps(event) + "\n")

    from iotad.kernel.model import SpecError
    try:
        run_script(root, inputs, args.until, make_policy(args.policy, args.seed), record=False, sinks=[emit])
    except SpecError as exc:  # found as the engine builds its actions: a family too large, say
        return _fail(str(exc))
    out.flush()
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from iotad.esprit import EspritError
    from iotad.esprit.typesys import describe

    module = _load(args.file)
    if module is None:
        return 2
    try:
        factories = [module.factory(args.iota)] if args.iota else list(module.iotas.values())
    except EspritError as exc:
        return _fail(str(exc))
    console = Console()
    for factory in factories:
        info = factory.info
        params = ", ".join(f"{p}={v}" for p, v in factory.params.items())
        table = Table(title=f"iota {factory.name}" + (f" ({params})" if params else ""), title_justify="left")
        for column in ("channel", "direction", "type", "switching time"):
            table.add_column(column)
        for name, chan in info.channels.items():
            size = "" if chan.size is None else f"[{chan.size}]"
            table.add_row(f"{name}{size}", chan.direction, describe(chan.type) if chan.type else "-",
                          f"{chan.switching:g}" if not isinstance(chan.switching, str) else chan.switching)
        console.print(table)
        if info.components:
            console.print("  includes: " + ", ".join(f"{n} ({i.iota})" for n, i in info.components.items()))
    return 0
