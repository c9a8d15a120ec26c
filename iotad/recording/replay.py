"""Replay: re-run one recorded node in virtual time against its recorded inputs and compare its
outputs with the recorded ones (`replay_node`); or republish a recording on zenoh (`republish`).

The node is rebuilt from the spec stored in the recording; its inputs are the input events of
its own `@trace` (what it accepted, at the times it accepted them, in its clock), so the replay
needs no other node. Outputs must agree in order, channel, index and value; times may differ
by `tolerance` (a real process fires a little after its window opens, the replay exactly then).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

from iotad.node_host.wire import START_KIND
from iotad.recording.conformance import align_paths, describe, first_difference, split_runs
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import Recording, start_time
from iotad.recording.values import values_close


@dataclass
class ReplayResult:
    node: str
    recorded: list[dict]
    replayed: list[dict]
    tolerance: float
    divergence: int | None = None   # index into the compared sequences of the first disagreement
    reason: str = ""
    max_time_error: float = 0.0
    kinds: tuple = ("output",)
    reordered: int = 0              # replayed events taken out of order (free replay, real time)
    real_time: bool = False         # the recording's clock was real
    guided: bool = False            # the node's firings followed the recording's times
    # free replay of a real-time recording: firings the process made later than the tolerance
    # after the replay had them due, each replayed at its recorded time: (recorded event, due)
    late: list = field(default_factory=list)
    # where a run's trace misses events the recording never heard (`Recording.trace_gaps`): the
    # run is replayed up to there, as its state after them is unknown; one line each
    gaps: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.divergence is None

    def lines(self, context: int = 3) -> list[str]:
        if self.ok:
            if self.guided:
                return [f"{self.node}: replay agrees: {len(self.recorded)} {'/'.join(self.kinds)} events, every "
                        f"value computed again, each firing at its recorded time"] + self._lateness() + self._gaps()
            order = (f"; {self.reordered} in another order than the replay's, within the tolerance"
                     if self.reordered else "")
            return [f"{self.node}: replay agrees: {len(self.recorded)} {'/'.join(self.kinds)} events, "
                    f"largest time difference {self.max_time_error:.3g} (tolerance {self.tolerance:g}){order}"] \
                + self._lateness() + self._gaps()
        k = self.divergence
        out = [f"{self.node}: replay diverges at {'/'.join(self.kinds)} event #{k}: {self.reason}"]
        lo = max(0, k - context)
        for title, events in (("recorded", self.recorded), ("replayed", self.replayed)):
            out.append(f"  {title}:")
            for j in range(lo, min(len(events), k + context + 1)):
                mark = ">>" if j == k else "  "
                out.append(f"   {mark} #{j} {describe(events[j])}")
            if k >= len(events):
                out.append(f"   >> #{k} (none: the {title} run ends here)")
        out += self._lateness() + self._gaps()
        if self.guided:
            out.append(f"  (each firing at its recorded time; 'iotad check FILE --node {self.node}' says which "
                       f"rule of the spec it breaks)")
        elif self.real_time:
            out.append("  (a free re-run of a real-time recording: it fires at exact times, the process fired "
                       "with its clock's jitter; without --free the replay follows the recorded firing times: "
                       "docs/checking.md)")
        return out


    def _gaps(self) -> list[str]:
        return [f"  {gap}" for gap in self.gaps]

    def _lateness(self) -> list[str]:
        """The firings the process made later than the tolerance (up to the divergence): guided,
        after their windows closed; free, after the replay has them due, and replayed where the
        recording has them."""
        late = self.late
        if not self.ok:
            until = float(self.recorded[min(self.divergence, len(self.recorded) - 1)]["t"]) if self.recorded else 0.0
            late = [(e, due) for e, due in late if float(e["t"]) <= until]
        if not late:
            return []
        event, due = late[0]
        worst, worst_due = max(late, key=lambda pair: float(pair[0]["t"]) - pair[1])
        if self.guided:
            what, when = "after their windows closed", "its window closed at"
        else:
            what, when = ("after the replay has them due, and are replayed where the recording has them, "
                          "not on time"), "it was due at"
        return [f"  {len(late)} firing(s) {'before that ' if not self.ok else ''}came later than the tolerance "
                f"{what}; the first, {describe(event)} ({when} t={due:.6g}, {float(event['t']) - due:.3g} late), "
                f"the latest {describe(worst)} ({float(worst['t']) - worst_due:.3g} late): 'iotad check' judges them"]


def node_root(recording: Recording, node: str) -> Any:
    from iotad.esprit.stored_spec import StoredSpecError, build_node  # the ESPRIT compiler: only when replaying

    specs = recording.specs
    if node not in specs:
        known = ", ".join(sorted(specs)) or "none"
        raise RecordingError(f"no spec of node {node!r} in {recording.path} (nodes with specs: {known})")
    try:
        return build_node(specs[node], node)
    except StoredSpecError as exc:
        raise RecordingError(str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - a stored spec that no longer builds: ESPRIT, Python, params
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise RecordingError(f"the spec of node {node!r} stored in {recording.path} does not build: "
                             f"{type(exc).__name__}: {first}") from None


def replay_node(recording: Recording, node: str, tolerance: float = 0.01,
                kinds: tuple = ("output",), reorder: bool | None = None, guided: bool | None = None) -> ReplayResult:
    """Re-run `node` against its recorded inputs; each run of its process (a restarted node has
    several) from its own start and initial state, as the process ran.

    `guided` (default: for real-time recordings): the node's own firings happen when and as the
    recording has them (which enabled action, at what time: what the process's clock decided),
    and every value is computed again from the spec and compared. This is replay as a debugger
    means it: the nondeterminism (inputs, timing) from the log, the computation done again.
    Otherwise (`--free`; by default for virtual-time recordings of the eager policy, whose timing
    is the engine's own) the node fires on its own at the eager policy's times, and times are
    compared too. A virtual run with `--seed` (the random policy) is replayed guided.

    `reorder` (free replay of a real-time recording, by default): events within `tolerance` of
    each other may agree in either order. A real process fires what is due within a few ms in
    the order its clock saw it, jitter included; the replay fires them at their exact times, in
    the engine's order. A virtual-time recording has that order exactly, and is compared in it."""
    info = recording.info
    real_time = info.get("clock") == "real"
    if guided is None:
        # a virtual run's times are the eager policy's, which a free replay repeats; any other
        # policy's (`iotad run --virtual --seed`) are in the recording alone
        guided = real_time or info.get("policy", "eager") != "eager"
    if reorder is None:
        reorder = real_time and not guided
    events = recording.process_trace(node)
    if not any(e.get("kind") != START_KIND for e in events):
        raise RecordingError(f"node {node!r} has no @trace events in {recording.path}")
    runs = split_runs(events, start_time(recording.specs.get(node)))
    # A virtual run says how far its engine ran: every node ran to there, so what the replay makes
    # after the node's last recorded event and by then is an event the recording lacks (a node
    # cut short). A real-time recording says no such thing of a node.
    run_end = None if real_time else recording.run_end
    recorded, replayed, late, gaps = [], [], [], []
    for number, (begun, run) in enumerate(runs):
        last = number == len(runs) - 1
        at = next((k for k, e in enumerate(run) if e.get("missed") is not None), None)
        if at is not None:
            # events the recording never heard: the spec's state after them is unknown (what
            # `iotad check` says too), so the run is replayed up to them, and to no known end
            missed = run[at]["missed"]
            gaps.append(f"GAP t={missed.get('from_t', 0):.6g}..{missed.get('to_t', 0):.6g}: {missed.get('missing', '?')} "
                        f"event(s) of its trace are not in this recording ({missed.get('why', '')}); replayed up to "
                        f"the gap, the {len(run) - at} event(s) recorded after it not")
            run, last = run[:at], False
        mine = [e for e in run if e.get("kind") in kinds]
        root = node_root(recording, node)
        if guided:
            again = _guided_run(root, begun, run, tolerance, kinds, late)
        else:
            again = _replay_run(root, begun, run, tolerance, kinds, until=run_end if last else None,
                                late=late if reorder else None)
        # A firing the recording may simply not have reached (it ended first, or the process was
        # killed at that instant; a real process, a little late, up to `tolerance` before) is not
        # a divergence.
        end = max((float(e["t"]) for e in run), default=begun)
        if last and run_end is not None:
            end = max(end, run_end)
        cut = end if last else math.nextafter(end, -math.inf)
        if reorder:
            cut -= tolerance
        while len(again) > len(mine) and again[-1]["t"] > cut:
            again.pop()
        recorded += mine
        replayed += again
    result = ReplayResult(node, recorded, replayed, tolerance, kinds=kinds, real_time=real_time, guided=guided,
                          late=late, gaps=gaps)
    for k in range(max(len(recorded), len(replayed))):
        if reorder and k < min(len(recorded), len(replayed)) and _moved_forward(recorded[k], replayed, k,
                                                                                 tolerance):
            result.reordered += 1
        if k >= len(recorded):
            result.divergence, result.reason = k, f"the replay has an extra event: {describe(replayed[k])}"
            break
        if k >= len(replayed):
            result.divergence, result.reason = k, f"the replay never produced {describe(recorded[k])}"
            break
        a, b = recorded[k], replayed[k]
        if not _agree(a, b):
            where = first_difference(a.get("value"), b.get("value")) \
                if a["action"] == b["action"] and isinstance(a.get("value"), (dict, list)) else ""
            result.divergence, result.reason = k, (f"recorded {describe(a)}, replayed {describe(b)}"
                                                   + (f" (recorded against replayed: {where})" if where else ""))
            break
        error = abs(float(a["t"]) - float(b["t"]))
        result.max_time_error = max(result.max_time_error, error)
        if error > tolerance:
            result.divergence, result.reason = k, (f"{describe(a)} was replayed at t={b['t']:.6g}: "
                                                   f"{error:.3g} apart, beyond the tolerance {tolerance:g}")
            break
    return result


def _agree(a: dict, b: dict) -> bool:
    return (a["action"], a.get("index"), a.get("kind")) == (b["action"], b.get("index"), b.get("kind")) \
        and values_close(a.get("value"), b.get("value"))


def _moved_forward(wanted: dict, replayed: list[dict], k: int, tolerance: float) -> bool:
    """If `replayed[k]` does not agree with the recorded event `wanted` but a later replayed event
    within `tolerance` of it does (both in time), move that one to place k; True if moved. None
    agrees, but one within `tolerance` is on the same channel and index while `replayed[k]` is
    not: that one is moved, so that the replay is compared in the recorded order and a value
    that differs is said as such, not as another event in its place."""
    t = float(wanted["t"])
    if _agree(wanted, replayed[k]) and abs(float(replayed[k]["t"]) - t) <= tolerance:
        return False
    same_channel = None
    for j in range(k + 1, len(replayed)):
        if float(replayed[j]["t"]) > t + tolerance:
            break
        if abs(float(replayed[j]["t"]) - t) > tolerance:
            continue
        if _agree(wanted, replayed[j]):
            replayed.insert(k, replayed.pop(j))
            return True
        if same_channel is None and _channel(replayed[j]) == _channel(wanted) != _channel(replayed[k]):
            same_channel = j
    if same_channel is not None:
        replayed.insert(k, replayed.pop(same_channel))
        return True
    return False


def _channel(event: dict) -> tuple:
    return event["action"], event.get("index"), event.get("kind")


def _replay_run(root: Any, begun: float, events: list[dict], tolerance: float, kinds: tuple,
                until: float | None = None, late: list | None = None) -> list[dict]:
    """The events of `kinds` that `root` makes when given the inputs of one recorded run, up to
    `until` (a virtual run's recorded end) or just past its last event.

    `late` (a real-time recording): a firing the recording has more than `tolerance` after the
    replay has it due, with nothing else of the node due before it, is fired at its recorded
    time, and (it, when it was due) goes on `late`. The process was late (under load, a firing
    comes after its deadline); fired on time, it would come before the recorded events between,
    see another state, and what follows would be compared out of order."""
    engine = Engine(root, VirtualClock(begun))
    mapping = align_paths((e.get("iota", "") for e in events), list(engine.leaves))
    # Inputs bound to an output inside the node (a composite) are delivered by that output's
    # firing in the replay too: their recorded input events are not posted again.
    bound = {id(target) for slot in engine.slots.values() for target in slot.targets}
    # Each input goes in where the recording has it: after the node's own firings recorded before
    # it, and before those recorded after it. In a virtual run of a whole system, an input and the
    # node's own firings often share an instant, in the order of the system's actions (another
    # node's output may come after this node's): the node alone would take the input first. In a
    # real-time run under load a firing can be late, after an input that came in meanwhile (it
    # then sees that input): replayed on time, it would fire before the input and may differ.
    recorded_fired = 0      # the node's firings (output, internal) the recording has so far
    firings = []            # the replay's, as its engine makes them
    engine.sinks.append(lambda e: firings.append(e) if e["kind"] in ("output", "internal") else None)
    engine.start()          # its windows open at the run's start, not at the first input

    def catch_up(until: float, count: int) -> None:
        """Fire what is due up to `until`, one firing at a time, while the replay has fired fewer
        than the recording's first `count`."""
        while len(firings) < count and not engine.halted:
            due = engine.next_due()
            if due > until:
                break
            if engine.now() < due:
                engine.clock.wait(due)
            if engine.fire_due(count - len(firings)) == 0 and engine.next_due() <= engine.now():
                break  # nothing could fire now (every due one waits out a switching time)

    for event in events:
        t, kind = float(event["t"]), event.get("kind")
        if kind in ("output", "internal"):
            recorded_fired += 1
            if late is not None:
                catch_up(t - tolerance, recorded_fired - 1)  # the firings recorded before it
                due = engine.next_due()
                this = (mapping[event.get("iota", "")], event["action"], event.get("index"))
                if len(firings) == recorded_fired - 1 and due < t - tolerance and engine.next_due_action() == this:
                    if engine.now() < t:
                        engine.clock.wait(t)
                    if engine.fire_due(1):
                        late.append((event, due))
            continue
        if kind != "input":
            continue
        slot = engine.slots.get((mapping[event.get("iota", "")], event["action"], event.get("index")))
        if slot is not None and id(slot) in bound:
            continue
        # what is due up to the input's instant, one firing at a time, while the recording has
        # fired more than the replay: a firing it has after the input waits for the input
        catch_up(t, recorded_fired)
        if engine.halted:
            break
        if engine.now() < t:
            engine.clock.wait(t)
        engine.deliver(mapping[event.get("iota", "")], event["action"], event.get("value"), event.get("index"))
    last = max((float(e["t"]) for e in events), default=begun) + tolerance
    engine.run(last if until is None else max(last, until))
    return _as_recorded(mapping, [e for e in engine.trace if e["kind"] in kinds])


def _guided_run(root: Any, begun: float, events: list[dict], tolerance: float, kinds: tuple,
                late: list) -> list[dict]:
    """The events of `kinds` that `root` makes when each of its firings is the one the recording
    has, at its time (the trace checker's way: an enabled instance of that channel and index, its
    value computed by the spec; none enabled: no firing). When each firing came is what happened,
    not judged here (`iotad check` says whether it was inside its window), but a firing later
    than the tolerance after its window closed goes on `late`, with when it closed."""
    from iotad.recording.conformance import TraceChecker

    checker = TraceChecker(root, tolerance=tolerance, start=begun)
    made: list[dict] = []
    checker.engine.sinks.append(lambda event: made.append(event) if event["kind"] in kinds else None)
    report = checker.check(events)
    late += [(events[f.position], f.due) for f in report.findings if f.code == "late" and f.due is not None]
    return _as_recorded(align_paths((e.get("iota", "") for e in events), list(checker.engine.leaves)), made)


def _as_recorded(mapping: dict[str, str], events: list[dict]) -> list[dict]:
    """Replayed events with the recording's names of their IOTAs (`mapping`: recorded -> leaf)."""
    reverse = {}
    for recorded_name, leaf in mapping.items():
        reverse.setdefault(leaf, recorded_name)
    return [dict(e, iota=reverse.get(e["iota"], e["iota"])) for e in events]


# ------------------------------------------------------------------------------------ live
def republish(recording: Recording, session: Any, *, rate: float = 1.0, start: float = 0.0, loop: bool = False,
              progress: Callable[[int, int], None] | None = None, stop: Callable[[], bool] = lambda: False) -> int:
    """Publish every message on its key at its recorded pace (divided by `rate`), from `start`
    seconds into the recording. Attachments are fresh `[sequence, send_time_ns]`. Returns the count."""
    from iotad.node_host import wire

    # Paced by the senders' send times where the recording has them: a trace-sourced recording's
    # log times are burst arrivals (20 ms lumps), not when the messages were sent.
    def sent_at(message: Any) -> int:
        return message.publish_time or message.log_time

    messages = sorted((m for m in recording.messages if not m.topic.startswith("@")), key=sent_at)
    if not messages:
        return 0
    first = sent_at(messages[0]) + int(start * 1e9)
    messages = [m for m in messages if sent_at(m) >= first]
    publishers: dict[str, Any] = {}
    sequences: dict[str, int] = {}
    sent = 0
    try:
        while True:
            t0 = time.monotonic()
            for k, message in enumerate(messages):
                if stop():
                    return sent
                due = t0 + (sent_at(message) - first) / 1e9 / rate
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                publisher = publishers.get(message.topic)
                if publisher is None:
                    publisher = publishers[message.topic] = session.declare_publisher(message.topic)
                seq = sequences.get(message.topic, 0)
                sequences[message.topic] = seq + 1
                publisher.put(message.data, attachment=wire.encode_attachment(seq))
                sent += 1
                if progress is not None:
                    progress(k + 1, len(messages))
            if not loop:
                return sent
    finally:
        for publisher in publishers.values():
            publisher.undeclare()


def default_tolerance(recording: Recording) -> float:
    """Virtual-time recordings replay exactly; real ones get 10 ms (in spec time units)."""
    info = recording.info
    if info.get("clock") == "virtual":
        return 1e-9
    unit = info.get("time_unit") or 1.0
    try:
        return 0.01 / float(unit)
    except (TypeError, ValueError, ZeroDivisionError):
        return 0.01

