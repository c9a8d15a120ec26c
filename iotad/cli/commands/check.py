"""`iotad check`: check recorded traces against specs (each node against its own, or one node
against another spec: does it implement it?), and cross-check every message: what its sender
claims, what the wire carried, what its receiver got. See docs/checking.md for the algorithms and
their limits."""
from __future__ import annotations

import argparse
import json
import sys

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


LONG = 100_000  # messages in a recording past which check says what it is doing, on stderr


def run(args: argparse.Namespace) -> int:
    from iotad.recording.conformance import check_implements
    from iotad.cli import CliError
    from iotad.cli.commands.info import load
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
    specs = recording.specs
    if args.node and args.node not in specs:
        raise CliError(f"no spec of node {args.node!r} in {args.file} "
                       f"(nodes with specs: {', '.join(sorted(specs)) or 'none'})")
    if args.iota or args.param:
        raise CliError("--iota and --param apply to --spec; without --spec each node is checked against "
                       "its own spec, with the parameters it ran with")
    nodes = [args.node] if args.node else sorted(specs)
    if not nodes:
        raise CliError(f"{args.file} holds no node specs: nothing to check against")
    if not recording.messages and recording.complete:
        # specs and nothing else, in a whole file: what `iotad recover` keeps of a file cut short
        # before its first chunk (a virtual run writes its messages at the end), which every node
        # would "conform" to (a file still cut short is INCOMPLETE below: no pass either)
        raise CliError(f"{args.file} holds no events at all, only {len(specs)} spec(s): nothing to check "
                       f"(a recording cut short before any message was written?)")
    all_ok = True
    limit = 10**9 if args.all else 20
    # What cannot be checked is said, and is no pass: a node without a (readable) spec, a
    # recording cut short (its end is missing, and with it what happened there).
    unchecked = [] if args.node else _unchecked(recording, specs)
    for node in unchecked:
        print(f"{node}: NOT CHECKED: the recording holds no readable spec of it "
              f"(its spec/{node}.json attachment is missing or not a JSON object)")
    never = [] if args.node else _never_ran(recording, specs, unchecked)
    for node in never:
        print(f"{node}: NOT CHECKED: a node of the recorded system file that never ran (the recording holds "
              f"neither its spec nor any event of it: it never went live)")
    unchecked += never
    if not recording.complete:
        print(f"{args.file}: INCOMPLETE recording ({recording.truncated_reason or 'cut short'}): only what it "
              f"holds is checked, and a window still open where it ends is not judged; "
              f"'iotad recover {args.file}' rewrites it whole")
    if recording.run_error:
        print(f"{args.file}: the run that made it BROKE OFF with an error of iotad ({recording.run_error}): "
              f"only what it holds is checked")
    if recording.recovered_from:
        print(f"{args.file}: RECOVERED from {recording.recovered_from}: the run's end is not in it, so only what "
              f"it holds is checked")
    _merged_notes(recording, args.file)
    # a long recording takes a while per node (about 2 s per 100,000 events): say what is going on
    long = len(recording.messages) > LONG
    from iotad.recording.clock_offsets import widenings
    widened = widenings(recording)  # the nodes of hosts whose clocks were measured against the hub's
    partial = []  # nodes judged only up to a gap in their trace (events the recording never heard)
    for node in nodes:
        report = _check_node(recording, node, args, tolerance, long, widened.get(node))
        if report is None:
            unchecked.append(node)
            continue
        all_ok &= report.ok
        if report.partial:
            partial.append(node)
            if _one_hosts_file(recording):
                report.gaps.append("the recording of its own host holds what this one lacks: join every host's "
                                   "recording with 'iotad merge' and check the merged file")
        print("\n".join(report.lines(limit=limit)))
    conforms = all_ok
    delivered = None
    if not args.no_delivery:
        from iotad.recording.delivery import check_delivery
        if long:
            print(f"checking the delivery of {len(recording.messages):,} messages...", file=sys.stderr, flush=True)
        delivery = check_delivery(recording, tolerance=tolerance, node=args.node)
        print("\n".join(delivery.lines(limit=limit)))
        if delivery.checked:
            delivered = delivery.ok
            all_ok &= delivery.ok
    # a node judged only up to a gap is no pass, as a recording cut short is none: what it did
    # after the gap was not judged
    whole = recording.complete and not recording.run_error and not recording.recovered_from and not partial
    if all_ok and not unchecked and whole:
        verdict = "every node conforms to its spec" + (", every message was delivered as sent" if delivered else "")
    else:
        what = [w for w, bad in (("conformance", not conforms), ("delivery", delivered is False),
                                 (f"{len(unchecked)} node(s) not checked", unchecked),
                                 (f"{', '.join(partial)} judged only up to a gap in the trace", partial),
                                 ("the recording is incomplete", not recording.complete),
                                 ("it was recovered from a cut recording", recording.recovered_from),
                                 ("the run broke off", recording.run_error)) if bad]
        verdict = f"PROBLEMS FOUND ({' and '.join(what)})"
    print(f"check: {verdict} (tolerance {tolerance:g})")
    return 0 if all_ok and not unchecked and whole else 1


def _one_hosts_file(recording) -> bool:
    """Whether `recording` is one host's recording of a run over hosts (not their merge)."""
    run = recording.info.get("run")
    return isinstance(run, dict) and bool(run.get("host")) and not isinstance(recording.info.get("merged"), list)


def _merged_notes(recording, file: str) -> None:
    """A merged recording (`iotad merge`): each host gap it marks, as a note. What the host's own
    recording held is in the file; a gap says where one recording alone saw a host's events, or
    where none of the files may have."""
    from iotad.recording.merge import describe_gap, merged_gaps

    if not isinstance(recording.info.get("merged"), list):
        return
    gaps = merged_gaps(recording)
    print(f"{file}: merged from {', '.join(map(str, recording.info['merged']))}; "
          f"{len(gaps)} host gap(s) marked" + (":" if gaps else ""))
    for gap in gaps:
        print(f"  note: {describe_gap(gap)}")


def _check_node(recording, node: str, args: argparse.Namespace, tolerance: float, long: bool, widen=None):
    """The conformance report of one node against its own spec, or None (said why) when it cannot
    be checked. Its trace, decoded, is the bulk of the memory a check takes: it is read here, and
    let go before the next node's is read. `widen`: its host clock's bound over time
    (`iotad.recording.clock_offsets.Widening`), which its windows are widened by."""
    from iotad.cli import CliError
    from iotad.host.wire import START_KIND
    from iotad.recording.conformance import check_runs
    from iotad.recording.mcap_reader import start_time
    from iotad.recording.replay import node_root

    real_time = recording.info.get("clock") != "virtual"
    events = recording.process_trace(node)
    if long:
        print(f"checking {node} ({len(events):,} events)...", file=sys.stderr, flush=True)
    if args.node and not events and (real_time or recording.run_end is None):
        # nothing to judge it by; a virtual run's recorded end judges even a silent node
        raise CliError(f"node {node!r} has no @trace events in {args.file}")
    # a real-time node whose start is not recorded: from mid-run, or nothing but heartbeats
    if real_time and (events or recording.info.get("clock") == "real") \
            and not any(e.get("kind") == START_KIND for e in events):
        # recorded from mid-run (`iotad record` attached late): the state it was in is unknown
        print(f"{node}: NOT CHECKED: the recording holds no start of its engine (it began after the node "
              f"started), so the state the node was in is unknown")
        return None
    return check_runs(lambda: node_root(recording, node), events, node=node, tolerance=tolerance,
                      until=None if real_time else recording.run_end, start=start_time(recording.specs.get(node)),
                      widen=widen, widened=widen.line() if widen is not None else "")


def _never_ran(recording, specs: dict, unchecked: list[str]) -> list[str]:
    """Nodes of the recorded system file (a real-time run's system.toml) that the recording holds
    nothing of, where it was made to hold them (its key expressions cover their @trace)."""
    from iotad.host import wire
    from iotad.launcher.declaration import SystemFileError
    from iotad.host.wire import keyexpr_matches
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declaration = recorded_declaration(recording)
    except SystemFileError:
        return []  # the delivery check says what is wrong with it
    if declaration is None:
        return []
    names = declaration.file_nodes
    keys = recording.info.get("keys")
    system = recording.system or ""

    def covered(node: str) -> bool:
        trace = wire.trace_key(system, node)
        return not isinstance(keys, list) or any(isinstance(k, str) and keyexpr_matches(k, trace) for k in keys)

    seen = set(specs) | set(unchecked) | set(recording.nodes())
    return sorted(n for n in names if n not in seen and covered(n))


def _unchecked(recording, specs: dict) -> list[str]:
    """Nodes the recording says ran (listed in its metadata, or with events of their own on
    @trace) but holds no readable spec of. A virtual run's root composite is no node: the
    engine's violations about its external inputs are all it records."""
    listed = recording.info.get("nodes")
    named = {n for n in listed if isinstance(n, str)} if isinstance(listed, list) else set()
    # only the traces of nodes without a spec are read here: the others are checked anyway
    return sorted(n for n in (named | set(recording.nodes())) - set(specs)
                  if n and (n in named or any(e.get("kind") in ("input", "output", "internal")
                                              for e in recording.trace(n))))
