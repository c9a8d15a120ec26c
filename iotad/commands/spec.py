"""`iotad spec check|run|show`: the ESPRIT language from the command line."""
from __future__ import annotations

import argparse
import json
import sys

ORDER = 20


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("spec", help="check, run or show an ESPRIT specification (.iota)",
                            description=__doc__)
    commands = parser.add_subparsers(dest="spec_command", metavar="SUBCOMMAND")

    check = commands.add_parser("check", help="parse and check a spec; list errors and warnings")
    check.add_argument("file")
    check.set_defaults(func=cmd_check)

    run = commands.add_parser("run", help="run a spec in virtual time; print the trace as JSONL")
    run.add_argument("file")
    run.add_argument("--iota", help="which IOTA of the file (default: the last one)")
    run.add_argument("--param", action="append", default=[], metavar="K=V",
                     help="set a parameter (repeatable), e.g. --param N=3")
    run.add_argument("--inputs", metavar="SCRIPT.jsonl", help="input script: one {\"t\", \"action\", ...} a line")
    run.add_argument("--until", type=float, required=True, help="virtual time to run to")
    run.add_argument("--policy", choices=("eager", "random"), default="eager")
    run.add_argument("--seed", type=int, default=0, help="seed of the random policy")
    run.set_defaults(func=cmd_run)

    show = commands.add_parser("show", help="print an IOTA's interface as a table")
    show.add_argument("file")
    show.add_argument("--iota", help="which IOTA of the file (default: all)")
    show.set_defaults(func=cmd_show)
    parser.set_defaults(func=lambda args: parser.print_help() or 0)


def _fail(message: str) -> int:
    print(message, file=sys.stderr)
    return 2


def _read(path: str) -> str | None:
    try:
        with open(path, encoding="utf-8") as handle:
            return handle.read()
    except (OSError, UnicodeDecodeError) as exc:
        print(f"iotad: error: cannot read {path}: {exc}", file=sys.stderr)
        return None


def cmd_check(args: argparse.Namespace) -> int:
    from iotad.esprit import check_text

    text = _read(args.file)
    if text is None:
        return 2
    errors, warnings = check_text(text, args.file)
    for diagnostic in errors + warnings:
        print(diagnostic, file=sys.stderr)
    if errors:
        print(f"{args.file}: {len(errors)} error(s), {len(warnings)} warning(s)", file=sys.stderr)
        return 2
    print(f"{args.file}: ok ({len(warnings)} warning(s))")
    return 0


def _param_value(text: str):
    """A --param value: JSON when it parses (3, 2.5, true, "x"), else the bare word (an enum member)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def cmd_run(args: argparse.Namespace) -> int:
    from iotad import trace
    from iotad.esprit import EspritError, load_file
    from iotad.policy import make_policy
    from iotad.script import ScriptError, parse_script, run_script

    params = {}
    for item in args.param:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            return _fail(f"iotad: error: --param {item!r}: expected NAME=VALUE")
        params[key.strip()] = _param_value(value.strip())
    inputs = []
    if args.inputs:
        text = _read(args.inputs)
        if text is None:
            return 2
        try:
            inputs = parse_script(text.splitlines(), args.inputs)
        except ScriptError as exc:
            return _fail(f"iotad: error: {exc}")
    try:
        module = load_file(args.file)
        root = module.factory(args.iota)(None, **params)
    except EspritError as exc:
        return _fail(str(exc))
    out = sys.stdout

    def emit(event: dict) -> None:
        out.write(trace.dumps(event) + "\n")

    run_script(root, inputs, args.until, make_policy(args.policy, args.seed), record=False, sinks=[emit])
    out.flush()
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.table import Table

    from iotad.esprit import EspritError, load_file
    from iotad.esprit.typesys import describe

    try:
        module = load_file(args.file)
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
