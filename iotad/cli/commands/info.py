"""`iotad info`: what a recording holds: nodes, channels, message counts, duration, where each
motor joint was at the end, violations, gaps, and per binding how many messages were delivered,
lost, altered, duplicated or unexplained."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from iotad.cli import nonnegative_int
from iotad.cli.recordings import load

ORDER = 31

EPILOG = """\
example:
  iotad info recordings/fig2.mcap

Durations are seconds of wall-clock time (virtual time units for an in-process recording).
See also: 'iotad check FILE' (conformance), 'iotad replay FILE --node PATH',
'iotad plot FILE -o OUT.png', 'iotad export FILE -o OUT.mcap --json' (Foxglove),
'iotad recover FILE' (a recording marked INCOMPLETE)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("info", help="summarise a recording: nodes, channels, counts, violations, gaps",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording (from 'iotad run' or 'iotad record')")
    parser.add_argument("--violations", type=nonnegative_int, default=10, metavar="N",
                        help="list at most N violations, gaps and launcher events each (default 10)")
    parser.set_defaults(func=run)


def _launcher_line(event: dict, first_ns: int) -> str:
    """`   0.334 s  live     scheduler      pid 26749` (seconds in the nodes' clock, as every t of the
    report: from their origin; from the recording's first message where the specs give none)."""
    t_ns = event.get("t_ns") or event.get("log_time") or first_ns
    what = event.get("event", "?")
    node = event.get("node") or "(launcher)"
    parts = [f"{(t_ns - first_ns) / 1e9:8.3f} s  {what:<8} {node:<14}"]
    if event.get("pid") is not None:
        parts.append(f"pid {event['pid']}")
    if event.get("code") is not None:
        parts.append(f"exit code {event['code']}")
    if event.get("restarts"):
        parts.append(f"restarts {event['restarts']}")
    if event.get("host"):
        parts.append(f"host {event['host']}")
    if event.get("message"):
        parts.append(f"- {event['message']}")
    return "  ".join(parts)


def _clocks(recording) -> None:
    """Each measured host's clock over the run, one line each (docs/hosts.md "Clocks")."""
    from iotad.recording.clock_offsets import CLOCK_EVENTS

    offsets = recording.clock_offsets()
    if not offsets:
        return
    violations = {}
    for event in recording.launcher_events():
        if event.get("event") == CLOCK_EVENTS[1]:
            violations[event.get("host")] = violations.get(event.get("host"), 0) + 1
    print("  clocks (offset to the hub's, and the bound it is known within):")
    for host, readings in sorted(offsets.items()):
        low, high = min(r.offset for r in readings), max(r.offset for r in readings)
        least, most = min(r.bound for r in readings), max(r.bound for r in readings)
        print(f"    host {host}: {len(readings)} measurement(s), offset {low * 1e3:+.3f} to {high * 1e3:+.3f} ms, "
              f"bound {least * 1e3:.3f} to {most * 1e3:.3f} ms, {violations.get(host, 0)} clock violation(s)")


def _joints_at_the_end(trace: list[dict], unit: float, names: dict[str, list[str]] | None = None) -> list[str]:
    """Where each joint of a motor node (a node with `joint_status[i]` outputs: the CAN motor
    node's) was when the recording ends: a robot whose axes went to FAULT and stayed there (a
    controller restarted, a trip) stops, with no violation to say so; this says it."""
    last: dict[str, dict[int, dict]] = {}   # node -> joint -> its last status
    since: dict[str, dict[int, tuple]] = {}  # node -> joint -> (when, event) its phase became that one
    for event in trace:
        value = event.get("value")
        if event.get("kind") != "output" or event.get("action") != "joint_status" or not isinstance(value, dict):
            continue
        node, joint = event["node"], event.get("index")
        before = last.setdefault(node, {}).get(joint)
        if before is None or (before.get("phase"), before.get("lost")) != (value.get("phase"), value.get("lost")):
            since.setdefault(node, {})[joint] = (float(event["t"]) * unit, value.get("event"))
        last[node][joint] = value
    lines = []
    for node, joints in sorted(last.items()):
        groups: dict[tuple, list[int]] = {}
        for joint, value in sorted(joints.items(), key=lambda item: (item[0] is None, item[0] or 0)):
            groups.setdefault((value.get("phase"), bool(value.get("lost"))), []).append(joint)
        parts = []
        for (phase, lost), members in sorted(groups.items(), key=lambda item: (item[0][0] != "ARMED", str(item[0]))):
            state = f"{phase}{' and LOST' if lost else ''}"
            if phase == "ARMED" and not lost:
                parts.append(f"{len(members)} of {len(joints)} joints ARMED")
                continue
            first = min(since[node][j][0] for j in members)
            causes = sorted({str(since[node][j][1]) for j in members})  # the events that brought them there
            known = (names or {}).get(node) or []  # by the joint map's names where the recording has them
            shown = [f"{j} ({known[j]})" if isinstance(j, int) and j < len(known) else str(j) for j in members]
            parts.append(f"joint(s) {', '.join(shown)} {state} since t={first:.3f} s "
                         f"({'/'.join(causes)})")
        lines.append(f"  joints at the end: {node}: {'; '.join(parts)}")
    return lines


def _delivery(recording, limit: int) -> None:
    """The per-binding delivery summary (`iotad check` has the full report: docs/checking.md)."""
    from iotad.recording.delivery import check_delivery
    from iotad.recording.replay import default_tolerance

    report = check_delivery(recording, tolerance=default_tolerance(recording))
    print(f"  {report.summary()}")
    if report.checked:
        for line in report.brief(limit):
            print(f"  {line}")


def _host_gaps(recording, limit: int) -> None:
    """A merged recording's (`iotad merge`): where a host's events are missing, and which files it joined."""
    from iotad.recording.merge import describe_gap, merged_gaps

    merged = recording.info.get("merged")
    if not isinstance(merged, list):
        return
    gaps = merged_gaps(recording)
    print(f"  merged from: {', '.join(map(str, merged))}; host gaps: {len(gaps)}")
    for gap in gaps[:limit]:
        print(f"    {describe_gap(gap)}")


def run(args: argparse.Namespace) -> int:
    recording = load(args.file)
    info = recording.info
    state = "complete" if recording.complete else f"INCOMPLETE (no footer: {recording.truncated_reason or 'cut short'}; " \
                                                  f"run 'iotad recover {args.file}')"
    print(f"{args.file}: {state}")
    if recording.run_error:
        print(f"  the run BROKE OFF with an error of iotad: {recording.run_error}")
    if recording.recovered_from:
        print(f"  RECOVERED by 'iotad recover' from {recording.recovered_from}: what came after is not in it")
    policy = info.get("policy")
    chosen = "" if policy in (None, "eager") else \
        f"   policy: {policy}" + (f" (seed {info['seed']})" if "seed" in info else "")
    if isinstance(info.get("nodes"), dict):  # a policy per node (iotad.kernel.policy.PerNode)
        chosen += f" ({info.get('default', 'eager')}; " + \
            ", ".join(f"{node}: {name}" for node, name in info["nodes"].items()) + ")"
    print(f"  system: {recording.system or '?'}   clock: {info.get('clock', '?')}   writer: {info.get('writer', '?')}"
          f"{chosen}   format: {recording.format_version}")
    derived = sum(1 for m in recording.messages if m.derived)
    print(f"  duration: {recording.duration():.3f} s   messages: {len(recording.messages) - derived}"
          + (f" (and {derived} read out of bursts)" if derived else "") + "   "
          f"attachments: {', '.join(a.name for a in recording.attachments) or 'none'}")
    specs = recording.specs
    trace = recording.trace()  # decoded once: every section below reads it
    trace_counts: dict[str, int] = {}
    for event in trace:
        trace_counts[event["node"]] = trace_counts.get(event["node"], 0) + 1
    print("  nodes:")
    for node in recording.nodes():
        spec = specs.get(node)
        source = spec.get("source", {}) if spec else {}
        what = (source.get("iota") or source.get("ref", "").rpartition(":")[2]
                or Path(source.get("file") or "?").name) if spec else "no spec"
        print(f"    {node:<24} {what:<20} {trace_counts.get(node, 0):>7} trace events")
    print("  channels (key, messages, type):")
    for topic, count in sorted(recording.topics().items()):
        schema = recording.schema_of(topic)
        print(f"    {topic:<48} {count:>8}  {schema.name if schema else '-'}")
    from iotad.recording.urdf_robot import joint_names_of

    joint_names = {node: found for node, spec in recording.specs.items()
                   if (found := joint_names_of(spec.get("params"))) is not None}
    for line in _joints_at_the_end(trace, recording.time_unit, joint_names):
        print(line)
    violations = [event for event in trace if event.get("kind") == "violation"]
    print(f"  violations: {len(violations)}")
    for event in violations[:args.violations]:
        value = event.get("value") if isinstance(event.get("value"), dict) else {}
        # the action and the time, not `describe`'s value: a violation's value is its code and message
        index = "" if event.get("index") is None else f"[{event['index']}]"
        when = f" at t={event['t']:.6g}" if isinstance(event.get("t"), (int, float)) else ""
        print(f"    {event.get('node')}: {event.get('action')}{index}{when}: {value.get('violation')}: "
              f"{value.get('message')}")
    if len(violations) > args.violations:
        print(f"    ... {len(violations) - args.violations} more (--violations N lists more)")
    gaps = recording.gaps()
    print(f"  sequence gaps: {len(gaps)} ({sum(g.get('missing', 0) for g in gaps)} messages missing)")
    for gap in gaps[:args.violations]:
        process = gap.get("process")
        if isinstance(process, dict):  # a restart the recorder did not hear (wire.restart_note)
            print(f"    {gap['key']}: a new process (pid {process.get('pid')}) first heard at #{gap['got']}, its "
                  f"start and first {gap['got']} event(s) not; the one before would have sent #{gap.get('after')} next")
        else:
            print(f"    {gap['key']}: expected #{gap['expected']}, got #{gap['got']}")
    if len(gaps) > args.violations:
        print(f"    ... {len(gaps) - args.violations} more (--violations N lists more)")
    _host_gaps(recording, args.violations)
    _delivery(recording, args.violations)
    _clocks(recording)
    launcher = recording.launcher_events()
    if launcher:
        print(f"  launcher events: {len(launcher)}")
        # the nodes' clock (t of every trace event, violation and delivery line above): their origin
        origins = [spec["origin"] for spec in recording.specs.values()
                   if isinstance(spec, dict) and isinstance(spec.get("origin"), (int, float))]
        first = int(round(min(origins) * 1e9)) if origins else \
            min([m.log_time for m in recording.messages] + [e["t_ns"] for e in launcher if e.get("t_ns")])
        for event in launcher[:args.violations]:
            print("    " + _launcher_line(event, first))
        if len(launcher) > args.violations:
            print(f"    ... {len(launcher) - args.violations} more (--violations N lists more)")
    return 0
