"""Trace conformance: does a recorded trace obey a spec? (`iotad check`; docs/checking.md)

Both checks drive the kernel's own `Engine` in virtual time with a policy that never fires on
its own (`Hold`), so windows, switching times, enabling and ranges are computed by the one
implementation of docs/design.md section 4; the checker only chooses *which* enabled instance a
recorded firing was and *when* it fires (`Engine.fire_instance`).

- `check_trace(root, events)`: a node's full trace (inputs, outputs, internal events) against
  its own spec. Inputs are applied at their times; each recorded local firing must be an
  enabled instance with that channel, index and value, inside its window and switching time;
  a window that closes with nothing fired is reported. Deterministic: no search.
- `check_implements(spec_root, events)`: an external trace (inputs and outputs only) against
  another spec, whose internal actions are hidden. A bounded depth-first search chooses when
  hidden actions fire (earliest allowed time, or as late as the next observed event allows) and
  which enabled instance explains an observed output; it reports the first event that no
  explored behaviour explains.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import ActionInstance, Engine, plus
from iotad.kernel.types import to_plain
from iotad.node_host.wire import START_KIND
from iotad.recording.values import values_close

INF = math.inf


# Violations a node records that the checker finds on its own (with its time tolerance); the
# others (a rejected input, a malformed payload, a fault in the spec) only the node could see.
SELF_CHECKED = {"deadline_miss", "unreachable_window", "bad_window"}


class Hold:
    """A policy that never fires by itself: the checker fires instances at recorded times."""

    name = "hold"

    def choose(self, earliest: float, latest: float) -> float:
        return INF


class _Collect:
    """An engine sink that keeps the violations the engine itself finds (a plain object, so
    that copying an engine for the search copies its findings too)."""

    def __init__(self) -> None:
        self.violations: list[dict] = []

    def __call__(self, event: dict) -> None:
        if event["kind"] == "violation":
            self.violations.append(event)


@dataclass
class Finding:
    t: float
    code: str       # early, late, expired, not_enabled, wrong_value, switching_time, unknown_event, ...
    message: str
    position: int   # index of the recorded event it is about (-1: the end of the recording)
    due: float | None = None  # a late firing: when its window closed

    def __str__(self) -> str:
        return f"t={self.t:.6g} [{self.code}] {self.message}"


@dataclass
class Slack:
    """How close to its window an action fired: `after_open` = t - (te + l), `before_close` =
    (te + u) - t; the smallest of each over all firings, and the count."""

    label: str
    count: int = 0
    after_open: float = INF
    before_close: float = INF

    def add(self, lower_slack: float, upper_slack: float) -> None:
        self.count += 1
        self.after_open = min(self.after_open, lower_slack)
        self.before_close = min(self.before_close, upper_slack)


@dataclass
class CheckReport:
    node: str
    events: int = 0
    firings: int = 0
    findings: list[Finding] = field(default_factory=list)
    slack: dict[str, Slack] = field(default_factory=dict)
    recorded_violations: list[dict] = field(default_factory=list)
    tolerance: float = 0.0
    restarts: list[float] = field(default_factory=list)  # when later processes of the node started
    widened: str = ""  # how its windows were widened beyond the tolerance, said in the report ("": not)
    # Where its trace misses events the recording never heard (`Recording.trace_gaps`): one line
    # each, and how many recorded events after them were not judged
    gaps: list[str] = field(default_factory=list)
    unjudged: int = 0

    @property
    def ok(self) -> bool:
        return not self.findings

    @property
    def partial(self) -> bool:
        """Judged only up to a gap in its trace: no problem found is no pass for the rest."""
        return bool(self.gaps)

    def lines(self, limit: int = 20) -> list[str]:
        head = (f"{self.node}: {self.events} events, {self.firings} firings checked, "
                f"{len(self.findings)} problem(s)" + ("" if self.ok else f"; first: {self.findings[0]}")
                + (f"; JUDGED ONLY UP TO A GAP in its trace ({self.unjudged} event(s) after it not judged)"
                   if self.partial else ""))
        out = [head]
        if self.widened:
            out.append(f"  {self.widened}")
        out += [f"  {gap}" for gap in self.gaps]
        if self.restarts:
            out.append(f"  restarted at t={', t='.join(f'{t:.6g}' for t in self.restarts)}: each run of its "
                       f"process is checked from its own start")
        for finding in self.findings[:limit]:
            out.append(f"  {finding}")
        if len(self.findings) > limit:
            out.append(f"  ... {len(self.findings) - limit} more")
        judged = [v for v in self.recorded_violations if (v.get("value") or {}).get("violation") in SELF_CHECKED]
        if judged:
            out.append(f"  {len(judged)} timing violation(s) the node recorded were judged here with "
                       f"tolerance {self.tolerance:g}")
        if self.slack:
            out.append(f"  {'action':<28} {'firings':>7} {'after open':>11} {'before close':>13}")
            for label, slack in sorted(self.slack.items()):
                out.append(f"  {label:<28} {slack.count:>7} {_fmt(slack.after_open):>11} "
                           f"{_fmt(slack.before_close):>13}")
        return out


def _fmt(value: float) -> str:
    return "inf" if value == INF else f"{value:.4g}"


def describe(event: dict) -> str:
    """An event as messages name it: `output ack[0]=COMMIT at t=3.5`."""
    index = "" if event.get("index") is None else f"[{event['index']}]"
    value = event.get("value")
    shown = "" if value is None else f"={_short(value)}"
    return f"{event.get('kind')} {event.get('action')}{index}{shown} at t={event.get('t'):.6g}"


def _short(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def first_difference(a: Any, b: Any, path: str = "") -> str:
    """Where two plain values first differ, for a message that shows them cut short: "data[0]:
    44 against 45" ("" where they are the same)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in list(a) + [k for k in b if k not in a]:
            if key not in a or key not in b:
                return f"{path}.{key}: {'missing' if key not in a else _short(a[key])} against " \
                       f"{'missing' if key not in b else _short(b[key])}".lstrip(".")
            found = first_difference(a[key], b[key], f"{path}.{key}")
            if found:
                return found
        return ""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        for k, (x, y) in enumerate(zip(a, b)):
            found = first_difference(x, y, f"{path}[{k}]")
            if found:
                return found
        if len(a) != len(b):
            return f"{path or 'the value'}: {len(a)} elements against {len(b)}"
        return ""
    if values_close(a, b):
        return ""
    return f"{path.lstrip('.') or 'the value'}: {_short(a)} against {_short(b)}"


def label_of(instance: ActionInstance) -> str:
    label = instance.action.label
    if instance.index is not None:
        label = label.replace("[i]", f"[{instance.index}]")
        if f"[{instance.index}]" not in label:
            label = f"{label}[{instance.index}]"
    return label


def align_paths(recorded: Iterable[str], leaf_paths: list[str]) -> dict[str, str]:
    """Map the `iota` names a node recorded to leaf paths of a rebuilt engine: the one leaf of a
    plain node; otherwise the leaf sharing the longest tail of path components."""
    mapping = {}
    for name in set(recorded):
        if len(leaf_paths) == 1:
            mapping[name] = leaf_paths[0]
            continue
        parts = name.split("/")
        best, best_len = None, -1
        for leaf in leaf_paths:
            leaf_parts = leaf.split("/")
            common = 0
            while common < min(len(parts), len(leaf_parts)) and parts[-1 - common] == leaf_parts[-1 - common]:
                common += 1
            if common > best_len:
                best, best_len = leaf, common
        mapping[name] = best
    return mapping


def _new_engine(root: Any, start: float = 0.0) -> tuple[Engine, _Collect]:
    collect = _Collect()
    engine = Engine(root, VirtualClock(start), Hold(), record=False, sinks=[collect],
                    deadline_tolerance=INF, reject_early_inputs=False)
    engine.start()
    return engine, collect


def _value_of(instance: ActionInstance) -> Any:
    action = instance.action
    if action.value is None:
        return None
    value = action.value(instance.iota, instance.index)
    # as the engine records it: by the channel's type, which also knows value types defined in
    # Python (an ESPRIT `extern struct`, e.g. channels.mdl:MDL_PROGRAM) that plain to_plain does not
    kind = getattr(instance.slot, "type", None)
    return to_plain(value) if kind is None else kind.to_plain(value)


def tolerance_at(tolerance: float, widen: Callable[[float], float] | None, t: float) -> float:
    """The tolerance of a time judgement at t: the check's, plus the bound of the node's host
    clock then (`widen`, iotad/recording/clock_offsets.py; None: a clock not measured, exact)."""
    return tolerance if widen is None else tolerance + widen(t)


def _earliest(instance: ActionInstance) -> float:
    slot = instance.slot
    return max(instance.lower, plus(slot.last, slot.switching))


# ------------------------------------------------------------------------------------ own spec
class TraceChecker:
    """Checks one node's recorded trace against the node's own spec (see module doc)."""

    def __init__(self, root: Any, node: str = "", tolerance: float = 0.0, start: float = 0.0,
                 widen: Callable[[float], float] | None = None):
        """`widen(t)`: how much more than `tolerance` a window or switching time of an event at t
        is given (spec units): the bound of the node's host clock then (iotad/recording/clock_offsets.py)."""
        self.engine, self.collect = _new_engine(root, start)
        self.tolerance = tolerance
        self._widen = widen
        self.report = CheckReport(node or root.instance_name, tolerance=tolerance)
        self._leaf_paths = list(self.engine.leaves)
        self._reported_expired: set[tuple[int, int]] = set()
        self._seen_violations = 0
        # Inputs bound to an output inside the node (a composite): firing that output delivers
        # them, so their recorded input events are checked against it, not applied again.
        self._bound = {id(target) for slot in self.engine.slots.values() for target in slot.targets}

    def check(self, events: list[dict], until: float | None = None) -> CheckReport:
        mapping = align_paths((e.get("iota", "") for e in events), self._leaf_paths)
        report = self.report
        latest = -INF  # the latest time recorded so far: a node's trace never goes back in time
        judged = events
        for position, event in enumerate(events):
            if event.get("missed") is not None:
                # events of the node that the recording never heard (`Recording.trace_gaps`): its
                # spec's state after them is unknown (a counter, a mode), so every event after
                # them would be judged against the wrong state: wrong values, late and expired
                # windows that the node never had. Judged up to the gap; the rest is said, not judged.
                self._gap(event["missed"], len(events) - position)
                judged, until = events[:position], None
                break
            report.events += 1
            leaf = mapping.get(event.get("iota", ""), self._leaf_paths[0])
            t = float(event["t"])
            kind = event.get("kind")
            if t < latest - self.tolerance:
                # an edited or damaged recording: judged at the time the checker has reached, the
                # event would be blamed on its neighbours (a switching time "of -0.6 ms"); say
                # what is wrong with it, and judge the events after it
                self._find(t, "out_of_order", f"{describe(event)} is recorded after an event at t={latest:.6g}: "
                                              f"the node's trace goes back in time here", position)
                continue
            latest = max(latest, t)
            if kind == "violation":
                report.recorded_violations.append(event)
                value = event.get("value") or {}
                if value.get("violation") in SELF_CHECKED:
                    continue  # the checker judges that firing itself, with its tolerance
                self._find(t, "recorded_violation",
                           f"the node recorded a violation on {event.get('action')}: "
                           f"{value.get('violation')}: {value.get('message')}", position)
                continue
            self._advance(t, position, event, leaf)
            if kind == "input":
                self._input(event, leaf, t, position)
            elif kind in ("output", "internal"):
                self._local(event, leaf, t, position)
            else:
                self._find(t, "unknown_event", f"{describe(event)}: unknown kind {kind!r}", position)
            self._engine_violations(t, position)
        # without a known end, windows are judged up to the last event judged: a window that
        # closes after it may have fired in what the recording lacks (or after the recording ends)
        end = until if until is not None else (float(judged[-1]["t"]) if judged else 0.0)
        self._advance(end, -1, None, None)
        return report

    # -- steps
    def _gap(self, missed: dict, after: int) -> None:
        """The report's line for a gap in the trace, and the events after it, not judged."""
        report = self.report
        report.unjudged += after
        why = f" ({missed['why']})" if missed.get("why") else ""
        report.gaps.append(
            f"GAP t={missed.get('from_t', 0):.6g}..{missed.get('to_t', 0):.6g}: {missed.get('missing', '?')} event(s) "
            f"of its trace are not in this recording{why}; the {after} event(s) recorded after the gap "
            f"(this run of its process) are not judged, since the state of its spec after the missing "
            f"events is unknown")
    def _slack(self, t: float) -> float:
        return tolerance_at(self.tolerance, self._widen, t)

    def _find(self, t: float, code: str, message: str, position: int, due: float | None = None) -> None:
        self.report.findings.append(Finding(t, code, message, position, due))

    def _engine_violations(self, t: float, position: int) -> None:
        found = self.collect.violations
        while self._seen_violations < len(found):
            violation = found[self._seen_violations]
            self._seen_violations += 1
            value = violation["value"]
            self._find(violation["t"], value["violation"], value["message"], position)

    def _advance(self, t: float, position: int, event: dict | None, leaf: str | None) -> None:
        """Move to time t; every window that closed before t with nothing fired is a finding."""
        engine = self.engine
        slack = self._slack(t)
        for instance in engine.instances:
            if not instance.enabled or instance.upper + slack >= t:
                continue
            if event is not None and instance.leaf.path == leaf and instance.action.channel == event.get("action") \
                    and instance.index == event.get("index"):
                continue  # the event itself may be this firing, late: reported as such
            key = (instance.rank, instance.gen)
            if key in self._reported_expired:
                continue
            self._reported_expired.add(key)
            after = f"the next event is {describe(event)}" if event is not None else \
                f"the recording ends at t={t:.6g}"
            self._find(instance.upper, "expired",
                       f"{label_of(instance)} was enabled at t={instance.te:.6g} and had to fire by "
                       f"t={instance.upper:.6g}; it never fired ({after})", position)
        if t > engine.now():
            engine.run(until=t)

    def _input(self, event: dict, leaf: str, t: float, position: int) -> None:
        engine = self.engine
        channel, index = event["action"], event.get("index")
        slot = engine.slots.get((leaf, channel, index))
        if slot is None or slot.channel.direction != "input":
            self._find(t, "unknown_event", f"{describe(event)}: the spec has no such input channel", position)
            return
        if id(slot) in self._bound:
            if slot.last != t:
                self._find(t, "not_enabled", f"{describe(event)}: a bound input, but no output bound to it "
                           f"fired at t={t:.6g}", position)
            return
        if t < plus(slot.last, slot.switching) - self._slack(t):
            self._find(t, "switching_time",
                       f"{describe(event)} came {t - slot.last:.6g} after the previous one at "
                       f"t={slot.last:.6g}, sooner than its switching time {slot.switching:g}", position)
        engine.post(leaf, channel, event.get("value"), index, t=max(t, engine.now()))
        engine.run(until=max(t, engine.now()))

    def _local(self, event: dict, leaf: str, t: float, position: int) -> None:
        engine, report = self.engine, self.report
        channel, index, value = event["action"], event.get("index"), event.get("value")
        candidates = [i for i in engine.instances
                      if i.leaf.path == leaf and i.action.channel == channel and i.index == index]
        if not candidates:
            self._find(t, "unknown_event", f"{describe(event)}: the spec has no such action", position)
            return
        direction = candidates[0].slot.channel.direction
        if direction != event.get("kind"):  # the kernel records a firing with its channel's direction
            self._find(t, "unknown_event", f"{describe(event)}: {channel} is an {direction} channel of the spec",
                       position)
        enabled = [i for i in candidates if i.enabled]
        if not enabled:
            self._find(t, "not_enabled", f"{describe(event)}: no action on {channel} was enabled "
                       f"(every precondition was false)", position)
            return
        matching = []
        for instance in enabled:
            try:
                if values_close(_value_of(instance), value):
                    matching.append(instance)
            except Exception:  # noqa: BLE001 - a value the spec cannot compute matches nothing
                continue
        if not matching:
            options = ", ".join(f"{label_of(i)}={_short(_value_of_safe(i))}" for i in enabled)
            # values too long to show whole look alike cut short: say where the first one differs
            where = first_difference(event.get("value"), _value_of_safe(enabled[0])) \
                if len(enabled) == 1 and isinstance(event.get("value"), (dict, list)) else ""
            differs = f" (recorded against the spec's: {where})" if where else ""
            self._find(t, "wrong_value", f"{describe(event)}: the spec allows only {options} here{differs}",
                       position)
            matching = enabled  # keep the state in step with what the node did
        slack = self._slack(t)
        inside = [i for i in matching if i.lower - slack <= t <= i.upper + slack]
        instance = (inside or matching)[0]
        slot = instance.slot
        name = label_of(instance)
        if t < instance.lower - slack:
            self._find(t, "early", f"{describe(event)} fired {instance.lower - t:.6g} before its window "
                       f"[{instance.lower:.6g}, {instance.upper:.6g}] opened ({name} enabled at "
                       f"t={instance.te:.6g})", position)
        elif t > instance.upper + slack:
            self._find(t, "late", f"{describe(event)} fired {t - instance.upper:.6g} after its window "
                       f"[{instance.lower:.6g}, {instance.upper:.6g}] closed ({name} enabled at "
                       f"t={instance.te:.6g})", position, due=instance.upper)
        if t < plus(slot.last, slot.switching) - slack:
            self._find(t, "switching_time", f"{describe(event)} came {t - slot.last:.6g} after the previous "
                       f"event on {channel} at t={slot.last:.6g}, sooner than its switching time "
                       f"{slot.switching:g}", position)
        generic = instance.action.label
        report.slack.setdefault(generic, Slack(generic)).add(t - instance.lower, instance.upper - t)
        report.firings += 1
        engine.fire_instance(instance, t)


def _value_of_safe(instance: ActionInstance) -> Any:
    try:
        return _value_of(instance)
    except Exception as exc:  # noqa: BLE001
        return f"<{type(exc).__name__}>"


def check_trace(root: Any, events: list[dict], *, node: str = "", tolerance: float = 0.0,
                until: float | None = None, start: float = 0.0,
                widen: Callable[[float], float] | None = None) -> CheckReport:
    """`start`: when the node's engine started, in its clock (`recording.start_time`); a node
    host's `start` event among `events` says it exactly and wins. `widen`: as `TraceChecker`'s."""
    events, start = split_start(events, start)
    return TraceChecker(root, node, tolerance, start, widen).check(events, until)


def split_runs(events: list[dict], start: float = 0.0) -> list[tuple[float, list[dict]]]:
    """A node's recorded trace as the runs of its process: (its engine start, its events) for
    each `start` record (a restarted node has one per process), or one run from `start` when the
    trace has none (an in-process recording)."""
    runs: list[tuple[float, list[dict]]] = []
    for event in events:
        if event.get("kind") == START_KIND:
            runs.append((float(event["t"]), []))
        elif runs:
            runs[-1][1].append(event)
        else:  # before any start record: in-process, or a recording without them
            runs.append((start, [event]))
    # no event at all is a run too: one that did nothing, which a run's known end can judge
    # (a node that should have fired by then and is silent is not "0 problems")
    return runs or [(start, [])]


def check_runs(build: Callable[[], Any], events: list[dict], *, node: str = "", tolerance: float = 0.0,
               start: float = 0.0, until: float | None = None, widen: Callable[[float], float] | None = None,
               widened: str = "") -> CheckReport:
    """`check_trace` of every run of a node's process, each from its own start and a fresh
    instance (`build()`): a restarted process starts from the spec's initial state, and a window
    open when the process died is not judged. One report; `restarts` lists the later starts.
    `until`: when the last run is known to have run to (a virtual run's end), past its last
    event: a window that closed before then and never fired is reported expired. `widen`: as
    `TraceChecker`'s; `widened`: the report's line that says so."""
    runs = split_runs(events, start)
    merged = CheckReport(node, tolerance=tolerance, widened=widened)
    for number, (begun, run) in enumerate(runs):
        last = number == len(runs) - 1
        report = TraceChecker(build(), node, tolerance, begun, widen).check(run, until=until if last else None)
        merged.events += report.events
        merged.firings += report.firings
        merged.findings += report.findings
        merged.recorded_violations += report.recorded_violations
        merged.gaps += report.gaps
        merged.unjudged += report.unjudged
        for label, slack in report.slack.items():
            total = merged.slack.setdefault(label, Slack(label))
            total.count += slack.count
            total.after_open = min(total.after_open, slack.after_open)
            total.before_close = min(total.before_close, slack.before_close)
        if number:
            merged.restarts.append(begun)
    return merged


def split_start(events: list[dict], start: float = 0.0) -> tuple[list[dict], float]:
    """(the events without engine-start records, the start time): a node host's first @trace
    event (kind `start`) is when its engine evaluated every precondition first."""
    found = [e for e in events if e.get("kind") == START_KIND]
    if not found:
        return events, start
    return [e for e in events if e.get("kind") != START_KIND], float(found[0]["t"])


# ------------------------------------------------------------------------------------ implements
@dataclass
class ImplementsReport:
    node: str
    spec: str
    events: int
    ok: bool
    explained: int                     # how many events some behaviour of the spec explains
    reasons: list[str] = field(default_factory=list)
    explored: int = 0
    exhausted: bool = False            # the search budget ran out: the answer is not final
    first_unexplained: dict | None = None
    widened: str = ""                  # how its times were widened beyond the tolerance ("": not)

    def lines(self) -> list[str]:
        said = [f"  {self.widened}"] if self.widened else []
        if self.ok:
            return [f"{self.node} implements {self.spec} on this trace: {self.events} external events "
                    f"explained ({self.explored} search steps)"] + said
        where = describe(self.first_unexplained) if self.first_unexplained else "the end of the trace"
        head = (f"{self.node} does not implement {self.spec} on this trace: the spec cannot explain "
                f"event #{self.explained} ({where})")
        if self.exhausted:
            head = f"inconclusive: search budget ({self.explored} steps) ran out before event #{self.explained} " \
                   f"({where}) was explained"
        return [head] + said + [f"  {reason}" for reason in self.reasons[:8]]


class ImplementsChecker:
    """Bounded search for a behaviour of `spec_root` whose external trace is `events`."""

    def __init__(self, spec_root: Any, tolerance: float = 0.0, budget: int = 20_000, max_hidden: int = 64,
                 start: float = 0.0, widen: Callable[[float], float] | None = None):
        self.root = spec_root
        self.tolerance, self.budget, self.max_hidden = tolerance, budget, max_hidden
        self._widen = widen  # as TraceChecker's
        engine, _ = _new_engine(spec_root, start)
        self.flat = engine.flat
        self.outputs = {}  # root channel name -> leaf endpoint
        self.inputs = {}
        for name, (direction, endpoint) in engine.flat.external.items():
            (self.outputs if direction == "output" else self.inputs)[name] = endpoint
        # (path, channel, index); index None: the whole family (or a plain channel) is external
        self._external = {(e.path, e.channel, e.index) for e in self.outputs.values()}
        self._start = engine
        # Specs, functions and types are shared by every copy of the engine: never copy them.
        self._memo_base = {}
        for leaf in engine.flat.leaves:
            spec = leaf.iota.iota_spec
            self._memo_base[id(spec)] = spec
            for channel in spec.channels.values():
                self._memo_base[id(channel)] = channel
                if channel.type is not None:
                    self._memo_base[id(channel.type)] = channel.type
            for action in spec.actions:
                self._memo_base[id(action)] = action
        self._memo_base[id(self.root)] = self.root
        self._memo_base[id(engine.flat)] = engine.flat

    def _copy(self, engine: Engine) -> Engine:
        return copy.deepcopy(engine, dict(self._memo_base))

    def hidden(self, instance: ActionInstance) -> bool:
        path, channel = instance.leaf.path, instance.action.channel
        return (path, channel, None) not in self._external and (path, channel, instance.index) not in self._external

    def check(self, events: list[dict], node: str = "", spec_name: str = "", until: float | None = None) -> ImplementsReport:
        events = [e for e in events if e.get("kind") in ("input", "output")]
        end = until if until is not None else (float(events[-1]["t"]) if events else 0.0)
        report = ImplementsReport(node, spec_name or self.root.instance_name, len(events), False, 0)
        best = -1
        reasons: dict[int, list[str]] = {}
        # A stack entry: (engine, position of the next event, hidden firings since the last event)
        stack: list[tuple[Engine, int, int]] = [(self._copy(self._start), 0, 0)]
        steps = 0
        while stack:
            if steps >= self.budget:
                report.exhausted = True
                break
            steps += 1
            engine, position, hidden_run = stack.pop()
            if position > best:
                best = position
            if position == len(events):
                problem = self._expired(engine, end)
                if problem is None:
                    report.ok, report.explained, report.explored = True, len(events), steps
                    return report
                reasons.setdefault(position, []).append(problem)
                continue
            event = events[position]
            t = float(event["t"])
            children: list[tuple[Engine, int, int]] = []
            late_children: list[tuple[Engine, int, int]] = []
            if hidden_run < self.max_hidden:
                for instance in list(engine.instances):
                    if not instance.enabled or not self.hidden(instance):
                        continue
                    earliest = max(_earliest(instance), engine.now())
                    slack = tolerance_at(self.tolerance, self._widen, t)
                    if earliest > t + slack or earliest > instance.upper + slack:
                        continue
                    latest = min(instance.upper, t)
                    for when, bucket in ((earliest, children), (latest, late_children)):
                        if when is not earliest and abs(when - earliest) <= 1e-12:
                            continue
                        child = self._fire_hidden(engine, instance, when, reasons, position)
                        if child is not None:
                            bucket.append((child, position, hidden_run + 1))
            applied = self._apply(engine, event, position, reasons)
            # Try, last pushed first: hidden firings at their earliest, then the event itself,
            # then hidden firings as late as possible.
            stack.extend((c, position, h) for c, position, h in reversed(late_children))
            stack.extend((c, position + 1, 0) for c in reversed(applied))
            stack.extend(reversed(children))
        report.explained = max(best, 0)
        report.explored = steps
        if best < len(events):
            report.first_unexplained = events[best] if best >= 0 else None
        report.reasons = reasons.get(best, [])
        return report

    # -- moves
    def _expired(self, engine: Engine, t: float) -> str | None:
        for instance in engine.instances:
            if instance.enabled and instance.upper + tolerance_at(self.tolerance, self._widen, t) < t:
                return (f"{label_of(instance)} (enabled at t={instance.te:.6g}) had to fire by "
                        f"t={instance.upper:.6g}, and nothing observed lets it")
        return None

    def _advance(self, engine: Engine, t: float) -> str | None:
        problem = self._expired(engine, t)
        if problem is None and t > engine.now():
            engine.run(until=t)
        return problem

    def _fire_hidden(self, engine: Engine, instance: ActionInstance, when: float, reasons: dict,
                     position: int) -> Engine | None:
        child = self._copy(engine)
        problem = self._advance(child, when)
        if problem is not None:
            reasons.setdefault(position, []).append(problem)
            return None
        twin = child.instances[engine.instances.index(instance)]
        child.fire_instance(twin, max(when, child.now()))
        return child

    def _apply(self, engine: Engine, event: dict, position: int, reasons: dict) -> list[Engine]:
        t = float(event["t"])
        name, index, value = event["action"], event.get("index"), event.get("value")
        why = reasons.setdefault(position, [])
        if event["kind"] == "input":
            if name not in self.inputs:
                why.append(f"{describe(event)}: the spec has no external input {name}")
                return []
            child = self._copy(engine)
            problem = self._advance(child, t)
            if problem is not None:
                why.append(problem)
                return []
            endpoint = self.inputs[name]
            slot = child.slots.get((endpoint.path, endpoint.channel, index if endpoint.index is None else endpoint.index))
            if slot is not None and t < plus(slot.last, slot.switching) - tolerance_at(self.tolerance, self._widen, t):
                why.append(f"{describe(event)} is sooner than the spec's switching time {slot.switching:g} "
                           f"after t={slot.last:.6g}")
                return []
            child.post(None, name, value, index, t=max(t, child.now()))
            child.run(until=max(t, child.now()))
            return [child]
        endpoint = self.outputs.get(name)
        if endpoint is None:
            why.append(f"{describe(event)}: the spec has no external output {name}")
            return []
        leaf_index = index if endpoint.index is None else endpoint.index
        found = []
        for k, instance in enumerate(engine.instances):
            if (instance.leaf.path, instance.action.channel, instance.index) != (endpoint.path, endpoint.channel, leaf_index):
                continue
            if not instance.enabled:
                continue
            try:
                if not values_close(_value_of(instance), value):
                    why.append(f"{describe(event)}: {label_of(instance)} would give {_short(_value_of_safe(instance))}")
                    continue
            except Exception:  # noqa: BLE001
                continue
            slack = tolerance_at(self.tolerance, self._widen, t)
            if not (_earliest(instance) - slack <= t <= instance.upper + slack):
                why.append(f"{describe(event)}: {label_of(instance)} may fire only in "
                           f"[{_earliest(instance):.6g}, {instance.upper:.6g}]")
                continue
            found.append(k)
        if not found and not any(i.enabled and (i.leaf.path, i.action.channel) == (endpoint.path, endpoint.channel)
                                 for i in engine.instances):
            why.append(f"{describe(event)}: no action on {name} is enabled in the spec here")
        children = []
        for k in found:
            child = self._copy(engine)
            problem = self._advance(child, t)
            if problem is not None:
                why.append(problem)
                continue
            child.fire_instance(child.instances[k], max(t, child.now()))
            children.append(child)
        return children


def check_implements(spec_root: Any, events: list[dict], *, node: str = "", spec_name: str = "",
                     tolerance: float = 0.0, budget: int = 20_000, until: float | None = None,
                     start: float = 0.0, widen: Callable[[float], float] | None = None,
                     widened: str = "") -> ImplementsReport:
    """`widen`, `widened`: as `check_runs`'s."""
    events, start = split_start(events, start)
    report = ImplementsChecker(spec_root, tolerance, budget, start=start, widen=widen).check(events, node, spec_name, until)
    report.widened = widened
    return report
