"""The verdict of `iotad check FILE`: every node of a recording checked against its own spec, with
the parameters it ran with, and every message's delivery, said line by line, then one verdict
line: what passes, and what is no pass (a node not checked, a recording cut short, a run that
broke off, a node judged only up to a gap). Raises `CheckError` where nothing can be checked."""
from __future__ import annotations

import sys
LONG = 100_000  # messages in a recording past which check says what it is doing, on stderr


class CheckError(Exception):
    """A check that cannot be made as asked (no such node, no specs, no events), in one line."""


def check_recording(recording, file: str, *, node: str | None = None, tolerance: float, delivery: bool = True,
                    limit: int = 20, own_params: bool = True) -> bool:
    """Check `recording` (read from `file`), its node `node` only where given; the lines go to
    stdout, the progress of a long check to stderr. True when everything passes. `own_params`:
    false where other parameters were asked for, which only a check against another spec takes."""
    specs = recording.specs
    if node and node not in specs:
        raise CheckError(f"no spec of node {node!r} in {file} "
                         f"(nodes with specs: {', '.join(sorted(specs)) or 'none'})")
    if not own_params:
        raise CheckError("--iota and --param apply to --spec; without --spec each node is checked against "
                         "its own spec, with the parameters it ran with")
    # a recording made to hold some nodes' traces (one host's own, or the hub's when a host keeps
    # its traces home) checks those; the others are said, and judged in the merge
    elsewhere = [] if node else sorted(n for n in specs if not recording.subscribed_to_trace(n))
    nodes = [node] if node else sorted(n for n in specs if n not in elsewhere)
    if not nodes and not elsewhere:
        raise CheckError(f"{file} holds no node specs: nothing to check against")
    if not recording.messages and recording.complete:
        # specs and nothing else, in a whole file: what `iotad recover` keeps of a file cut short
        # before its first chunk (a virtual run writes its messages at the end), which every node
        # would "conform" to (a file still cut short is INCOMPLETE below: no pass either)
        raise CheckError(f"{file} holds no events at all, only {len(specs)} spec(s): nothing to check "
                         f"(a recording cut short before any message was written?)")
    all_ok = True
    # What cannot be checked is said, and is no pass: a node without a (readable) spec, a
    # recording cut short (its end is missing, and with it what happened there).
    unchecked = [] if node else _unchecked(recording, specs)
    for name in unchecked:
        print(f"{name}: NOT CHECKED: the recording holds no readable spec of it "
              f"(its spec/{name}.json attachment is missing or not a JSON object)")
    never = [] if node else _never_ran(recording, specs, unchecked)
    for name in never:
        print(f"{name}: NOT CHECKED: a node of the recorded system file that never ran (the recording holds "
              f"neither its spec nor any event of it: it never went live)")
    unchecked += never
    for name in elsewhere:
        print(f"{name}: in another host's recording: this one was made to hold other nodes' traces "
              f"(check the merge of the hosts' recordings)")
    if not recording.complete:
        print(f"{file}: INCOMPLETE recording ({recording.truncated_reason or 'cut short'}): only what it "
              f"holds is checked, and a window still open where it ends is not judged; "
              f"'iotad recover {file}' rewrites it whole")
    if recording.run_error:
        print(f"{file}: the run that made it BROKE OFF with an error of iotad ({recording.run_error}): "
              f"only what it holds is checked")
    if recording.recovered_from:
        print(f"{file}: RECOVERED from {recording.recovered_from}: the run's end is not in it, so only what "
              f"it holds is checked")
    _merged_notes(recording, file)
    # a long recording takes a while per node (about 2 s per 100,000 events): say what is going on
    long = len(recording.messages) > LONG
    from iotad.recording.clock_offsets import widenings
    widened = widenings(recording)  # the nodes of hosts whose clocks were measured against the hub's
    partial = []  # nodes judged only up to a gap in their trace (events the recording never heard)
    for each in nodes:
        report = _check_node(recording, each, node, file, tolerance, long, widened.get(each))
        if report is None:
            unchecked.append(each)
            continue
        all_ok &= report.ok
        if report.partial:
            partial.append(each)
            if _one_hosts_file(recording):
                report.gaps.append("the recording of its own host holds what this one lacks: join every host's "
                                   "recording with 'iotad merge' and check the merged file")
        print("\n".join(report.lines(limit=limit)))
    conforms = all_ok
    delivered = None
    if delivery:
        from iotad.recording.delivery import check_delivery
        if long:
            print(f"checking the delivery of {len(recording.messages):,} messages...", file=sys.stderr, flush=True)
        report = check_delivery(recording, tolerance=tolerance, node=node)
        print("\n".join(report.lines(limit=limit)))
        if report.checked:
            delivered = report.ok
            all_ok &= report.ok
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
    return all_ok and not unchecked and whole




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


def _check_node(recording, node: str, asked: str | None, file: str, tolerance: float, long: bool, widen=None):
    """The conformance report of one node against its own spec, or None (said why) when it cannot
    be checked. Its trace, decoded, is the bulk of the memory a check takes: it is read here, and
    let go before the next node's is read. `widen`: its host clock's bound over time
    (`iotad.recording.clock_offsets.Widening`), which its windows are widened by."""
    from iotad.node_host.wire import START_KIND
    from iotad.recording.conformance import check_runs
    from iotad.recording.mcap_reader import start_time
    from iotad.recording.replay import node_root

    real_time = recording.info.get("clock") != "virtual"
    events = recording.process_trace(node)
    if long:
        print(f"checking {node} ({len(events):,} events)...", file=sys.stderr, flush=True)
    if asked and not events and (real_time or recording.run_end is None):
        # nothing to judge it by; a virtual run's recorded end judges even a silent node
        raise CheckError(f"node {node!r} has no @trace events in {file}")
    # a real-time node whose start is not recorded: from mid-run, or nothing but heartbeats
    if real_time and (events or recording.info.get("clock") == "real") \
            and not any(e.get("kind") == START_KIND for e in events):
        # recorded from mid-run (`iotad record` attached late): the state it was in is unknown
        print(f"{node}: NOT CHECKED: the recording holds no start of its engine (it began after the node "
              f"started), so the state the node was in is unknown")
        return None
    from iotad.recording.mcap_format import RecordingError

    try:
        built = [node_root(recording, node)]  # the first run's; each later run of the process gets its own
    except RecordingError as exc:
        if asked:
            raise CheckError(str(exc)) from None
        # one node whose code is not to be had here leaves the others to be judged
        print(f"{node}: NOT CHECKED: {exc}")
        return None
    return check_runs(lambda: built.pop() if built else node_root(recording, node), events, node=node,
                      tolerance=tolerance,
                      until=None if real_time else recording.run_end, start=start_time(recording.specs.get(node)),
                      widen=widen, widened=widen.line() if widen is not None else "")


def _never_ran(recording, specs: dict, unchecked: list[str]) -> list[str]:
    """Nodes of the recorded system file (a real-time run's system.toml) that the recording holds
    nothing of, where it was made to hold them (its key expressions cover their @trace)."""
    from iotad.launcher.system.declaration import SystemFileError
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declaration = recorded_declaration(recording)
    except SystemFileError:
        return []  # the delivery check says what is wrong with it
    if declaration is None:
        return []
    names = declaration.file_nodes
    seen = set(specs) | set(unchecked) | set(recording.nodes())
    return sorted(n for n in names if n not in seen and recording.subscribed_to_trace(n))


def _unchecked(recording, specs: dict) -> list[str]:
    """Nodes the recording says ran (listed in its metadata, or with events of their own on
    @trace) but holds no readable spec of. A virtual run's root composite is no node: the
    engine's violations about its external inputs are all it records."""
    listed = recording.info.get("nodes")
    named = {n for n in listed if isinstance(n, str)} if isinstance(listed, list) else set()
    # only the traces of nodes without a spec are read here: the others are checked anyway
    return sorted(n for n in (named | set(recording.nodes())) - set(specs)
                  if n and recording.subscribed_to_trace(n)
                  and (n in named or any(e.get("kind") in ("input", "output", "internal") for e in recording.trace(n))))
