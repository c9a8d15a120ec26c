"""`iotad info`: what a recording holds: nodes, channels, message counts, duration, violations, gaps."""
from __future__ import annotations

import argparse

ORDER = 31


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("info", help="summarise a recording: nodes, channels, counts, violations, gaps",
                            description=__doc__)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording")
    parser.add_argument("--violations", type=int, default=10, metavar="N", help="list at most N violations (default 10)")
    parser.set_defaults(func=run)


def load(path: str):
    """Read a recording for a command; a bad file is a one-line error."""
    from iotad.cli import CliError
    from iotad.recording import RecordingError, read_recording
    try:
        return read_recording(path)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{path}: {exc.strerror or exc}") from None


def run(args: argparse.Namespace) -> int:
    from iotad.checker import describe

    recording = load(args.file)
    info = recording.info
    state = "complete" if recording.complete else f"INCOMPLETE (no footer: {recording.truncated_reason or 'cut short'}; " \
                                                  f"run 'iotad recover {args.file}')"
    print(f"{args.file}: {state}")
    print(f"  system: {recording.system or '?'}   clock: {info.get('clock', '?')}   writer: {info.get('writer', '?')}")
    print(f"  duration: {recording.duration():.3f} s   messages: {len(recording.messages)}   "
          f"attachments: {', '.join(a.name for a in recording.attachments) or 'none'}")
    specs = recording.specs
    trace_counts: dict[str, int] = {}
    for event in recording.trace():
        trace_counts[event["node"]] = trace_counts.get(event["node"], 0) + 1
    print("  nodes:")
    for node in recording.nodes():
        spec = specs.get(node)
        source = spec.get("source", {}) if spec else {}
        what = (source.get("iota") or source.get("ref", "").rpartition(":")[2] or "?") if spec else "no spec"
        print(f"    {node:<24} {what:<20} {trace_counts.get(node, 0):>7} trace events")
    print("  channels:")
    for topic, count in sorted(recording.topics().items()):
        schema = recording.schema_of(topic)
        print(f"    {topic:<48} {count:>8}  {schema.name if schema else '-'}")
    violations = recording.violations()
    print(f"  violations: {len(violations)}")
    for event in violations[:args.violations]:
        value = event.get("value") or {}
        print(f"    {event['node']}: {describe(event)}: {value.get('violation')}: {value.get('message')}")
    gaps = recording.gaps()
    print(f"  sequence gaps: {len(gaps)} ({sum(g.get('missing', 0) for g in gaps)} messages missing)")
    for gap in gaps[:args.violations]:
        print(f"    {gap['key']}: expected #{gap['expected']}, got #{gap['got']}")
    launcher = recording.launcher_events()
    if launcher:
        print(f"  launcher events: {len(launcher)}")
        for event in launcher[:args.violations]:
            fields = {k: v for k, v in event.items() if k != "log_time"}
            print(f"    {fields}")
    return 0
