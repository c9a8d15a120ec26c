"""`iotad check`: check recorded traces against specs (each node against its own, or one node
against another spec: does it implement it?), and cross-check every message: what its sender
claims, what the wire carried, what its receiver got. See docs/checking.md for the algorithms and
their limits."""
from __future__ import annotations

import argparse
import json

from iotad.cli import nonnegative_float, positive_int

ORDER = 33

EPILOG = """\
examples:
  iotad check recordings/fig2.mcap                           every node against its own spec,
                                                             and every message's delivery
  iotad check recordings/fig2.mcap --node scheduler --all    one node, every problem listed
  iotad check recordings/fig2.mcap --node scheduler \\
      --spec nodes/scheduler/scheduler.iota --param N=2 --param T=0.5

--tolerance is in spec time units (time_unit seconds each). docs/checking.md explains the
algorithm, the slack columns, the delivery table and the limits of the search. See also: 'iotad replay FILE
--node PATH' (re-run a node and compare its outputs), 'iotad info FILE'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "check", help="check a recording against the specs (conformance, or implements another spec)",
        description="Without --spec: replay every node's spec (stored in the recording) guided by its "
                    "recorded trace: each firing must have been enabled and inside its window, no window may "
                    "expire unfired, switching times and ranges must hold; prints the slack of each action. "
                    "With --spec: check that the external trace of --node is a trace of SPEC (the paper's "
                    "'implements'), by bounded search over the spec's hidden choices; reports the first event "
                    "the spec cannot explain. Without --spec, also match every binding of the recorded "
                    "system file: each output its sender's trace claims against the message on the wire "
                    "and the receiver's input (delivered, lost, altered, duplicated, unexplained; latency "
                    "p50/p99/max), and every CAN bus frame by frame. Exit 0: conforms; 1: a problem "
                    "found; 2: bad input.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording (from 'iotad run' or 'iotad record')")
    parser.add_argument("--node", metavar="PATH", help="check only this node (required with --spec)")
    parser.add_argument("--spec", metavar="SPEC", help="another spec: an ESPRIT file (.iota) or file.py:Class")
    parser.add_argument("--iota", metavar="NAME", help="which IOTA of an ESPRIT file (default: the last)")
    parser.add_argument("--param", action="append", default=[], metavar="K=V",
                        help="a parameter of --spec (value parsed as JSON when it can be)")
    parser.add_argument("--tolerance", type=nonnegative_float, default=None, metavar="T",
                        help="slack allowed on times, in spec time units (default: exact for virtual-time "
                             "recordings, 10 ms for real ones)")
    parser.add_argument("--budget", type=positive_int, default=20_000, metavar="N",
                        help="search steps allowed for --spec (default 20000)")
    parser.add_argument("--all", action="store_true", help="list every problem, not the first 20")
    parser.add_argument("--no-delivery", action="store_true",
                        help="check each node against its spec only, not the delivery of its messages")
    parser.set_defaults(func=run)


def parse_params(items: list[str]) -> dict:
    from iotad.cli import CliError
    params = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key:
            raise CliError(f"--param {item!r}: expected K=V")
        if key in params:
            raise CliError(f"--param {key} is given twice")
        try:
            params[key] = json.loads(text)
        except ValueError:
            params[key] = text
    return params


def load_spec(reference: str, name: str, iota: str | None, params: dict):
    """An IOTA instance from an ESPRIT file or a Python reference; errors are one line."""
    from pathlib import Path

    from iotad.cli import CliError
    try:
        if reference.endswith(".iota") or Path(reference).suffix == ".iota":
            if not Path(reference).is_file():
                raise CliError(f"--spec {reference}: no such file")
            try:
                from iotad.esprit import load_iota
            except ImportError:
                raise CliError("ESPRIT specs need iotad.esprit, which is not installed here") from None
            return load_iota(reference, iota=iota, name=name, **params)
        from iotad.kernel.python_loader import LoadError, load_object
        try:
            cls = load_object(reference)
        except LoadError as exc:
            raise CliError(f"--spec: {exc}") from None
        return cls(name, **params)
    except CliError:
        raise
    except Exception as exc:  # noqa: BLE001 - spec errors (EspritError, SpecError) are one line
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CliError(f"--spec {reference}: {first}") from None



def run(args: argparse.Namespace) -> int:
    from iotad.recording.conformance import check_implements
    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.mcap_reader import start_time
    from iotad.recording.replay import default_tolerance

    recording = load(args.file)
    tolerance = default_tolerance(recording) if args.tolerance is None else args.tolerance
    if args.spec:
        if not args.node:
            raise CliError("--spec needs --node PATH: whose trace to check against it")
        if not args.spec.endswith(".iota") and ":" not in args.spec:
            raise CliError(f"--spec {args.spec}: expected an ESPRIT file (.iota) or file.py:Class")
        events = recording.trace(args.node)
        if not events:
            raise CliError(f"node {args.node!r} has no @trace events in {args.file} "
                           f"(nodes: {', '.join(recording.nodes()) or 'none'})")
        spec = load_spec(args.spec, args.node, args.iota, parse_params(args.param))
        from iotad.recording.clock_offsets import widenings
        widen = widenings(recording).get(args.node)  # its host's clock bound, where it was measured
        report = check_implements(spec, events, node=args.node, spec_name=args.spec, tolerance=tolerance,
                                  budget=args.budget, start=start_time(recording.specs.get(args.node)),
                                  widen=widen, widened=widen.line() if widen is not None else "")
        print("\n".join(report.lines()))
        return 0 if report.ok else 1
    from iotad.recording.verdict import CheckError, check_recording

    try:
        return 0 if check_recording(recording, args.file, node=args.node, tolerance=tolerance,
                                    delivery=not args.no_delivery, limit=10**9 if args.all else 20,
                                    own_params=not (args.iota or args.param)) else 1
    except CheckError as exc:
        raise CliError(str(exc)) from None
