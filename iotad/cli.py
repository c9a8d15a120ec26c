"""The `iotad` command line. Each subcommand lives in a module of `iotad.commands` that defines
`register(subparsers)`; this file only discovers them, so commands stay independent."""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import __version__, commands


class CliError(Exception):
    """A user-facing error: printed as one line, exit code 2, no traceback."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="iotad",
        description="A runtime of Input-Output Timed Automata (IOTAs) for robots that share motors: "
                    "specify, run, record, replay and check.",
        epilog="Run 'iotad COMMAND --help' for the options of a command.")
    parser.add_argument("--version", action="version", version=f"iotad {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = []
    for info in pkgutil.iter_modules(commands.__path__):
        modules.append(importlib.import_module(f"{commands.__name__}.{info.name}"))
    for module in sorted(modules, key=lambda m: (getattr(m, "ORDER", 50), m.__name__)):
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except CliError as exc:
        print(f"iotad: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    # Run as `python -m iotad.cli`, this module is `__main__`, whose CliError is not the one the
    # commands raise: delegate to the imported module so errors stay one line.
    from iotad.cli import main as imported_main
    sys.exit(imported_main())
