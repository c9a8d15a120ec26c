"""The engine: executes a system of IOTAs exactly as docs/design.md section 4 defines.

One heap of (fire time, rank, generation, action instance), SimPy-style. `rank` is the
declaration order (leaf, action, index), so among actions due at one instant the heap itself
yields them in the order the semantics prescribe; `generation` invalidates entries of windows
that were dropped. After each firing only the preconditions that read a cell the firing may have
written are re-evaluated (see `iotad.kernel.dependencies`), plus the fired action itself, whose window restarts.

Time never moves inside a firing: the do-block, the output value and the inputs it delivers
through bindings are one atomic step at one instant.
"""
from __future__ import annotations

import heapq
import math
from functools import partial
from types import MethodType
from typing import Any, Callable, Iterable

from iotad.kernel.clock import Clock, VirtualClock
from iotad.kernel.compose import Endpoint, Flat, Leaf, expand, flatten
from iotad.kernel.instant import running
from iotad.kernel.model import ALL_STATE, ANY, INDEX, Action, Channel, is_by_state
from iotad.kernel.policy import Eager
from iotad.kernel.types import BadValue, CheckedPlain, same_checks
from iotad.kernel.wire_delay import LaterDelivery

INF = math.inf
STOP = object()  # post this to a real clock's inbox to make `run` return

# A time the engine computes as a time plus a duration (window bounds, the end of a switching
# time) is rounded to 1e-9 of a time unit, a nanosecond where it is the second, as recordings
# hold times. Float sums drift (0.1 + 0.2 > 0.3): unrounded, an input sent exactly its
# switching time after the last (0.3 after 0.1 on /0.2) would be refused as early, and an output
# due at 0.8 after eight steps of 0.1 would fire at 0.7999999999999999, before an input at 0.8:
# an order no recording could explain. A duration of 0 is `t` itself, and rounding never goes
# before `t` (a real clock's times are not on the grid).
TIME_GRID = 1e9  # steps per time unit
GRID_STEP = 1 / TIME_GRID


def plus(t: float, duration: float) -> float:
    """`t + duration` on the engine's time grid."""
    if duration == 0:
        return t
    later = t + duration
    if later == INF or later == -INF:  # (a time before any event is -inf; a switching time may be inf)
        return later
    # round(x * 1e9) / 1e9 is the nearest grid point, a third of the cost of round(x, 9) on this
    # hot path; past 2**53 ns (104 days) the grid coarsens, which still keeps sums from drifting
    try:
        on_grid = round(later * TIME_GRID) / TIME_GRID
    except OverflowError:  # past 1.8e299 the product is inf: a time no run reaches, as it is
        return later
    return on_grid if on_grid >= t else t


# the violations by which an engine refuses an input event (`_deliver`); it is then not taken
INPUT_REFUSALS = ("bad_value", "switching_time")


class Slot:
    """One channel (one index of a family) of one leaf: its last event time and switching time."""

    __slots__ = ("leaf", "channel", "index", "switching", "last", "targets", "input_action", "type", "deliveries",
                 "dynamic", "do", "affects")

    def __init__(self, leaf: Leaf, channel: Channel, index: int | None):
        self.leaf, self.channel, self.index = leaf, channel, index
        self.switching = leaf.switching[channel.name]
        self.last = -INF
        self.type = channel.type
        self.targets: list[Slot] = []        # bound inputs an output delivers to
        self.deliveries: list[tuple[Slot, bool]] = []  # (target, its type checks what this one does)
        self.input_action: Action | None = None
        self.dynamic: tuple = ()  # its input action's writes `x[k]` (`_dynamic_writes`), when tracked
        self.do: Callable | None = None  # its input action's do-block bound (`bind`): do(value)
        self.affects: list | None = None  # instances its input action may affect (computed on first input)


class ActionInstance:
    """One locally controlled action at one index: its window while enabled."""

    __slots__ = ("leaf", "action", "index", "slot", "rank", "enabled", "gen", "te", "lower", "upper",
                 "fire_at", "affects", "iota", "when", "value", "do", "after", "before", "reads", "dynamic",
                 "failing", "reevaluate", "lower_bound", "upper_bound", "policy", "eager")

    def __init__(self, leaf: Leaf, action: Action, index: int | None, slot: Slot, rank: int):
        self.leaf, self.action, self.index, self.slot, self.rank = leaf, action, index, slot, rank
        self.iota = leaf.iota
        # the action's functions bound to (iota, index): called with no arguments
        self.when, self.value, self.do = (bind(action.when, leaf.iota, index), bind(action.value, leaf.iota, index),
                                          bind(action.do, leaf.iota, index))
        self.after, self.before = bind(action.lower, leaf.iota, index), bind(action.upper, leaf.iota, index)
        self.enabled, self.gen = False, 0
        self.te = self.lower = self.upper = self.fire_at = 0.0
        self.affects: list[ActionInstance] | None = None  # computed on first firing
        # itself, then `affects` without itself: what a firing re-evaluates, in that order
        self.reevaluate: list[ActionInstance] | None = None
        # a time bound that is a constant (`after=0.01`): its float, read without a call
        self.lower_bound, self.upper_bound = constant_bound(action.lower), constant_bound(action.upper)
        self.dynamic = _dynamic_writes(action)
        self.failing = False  # its precondition raised at its last evaluation
        self.reads = _concrete(action.reads, index)
        self.policy: Any = None  # its firing policy (the engine's, or its node's: `PerNode`)
        self.eager = True        # that policy is `Eager`: `_enable` schedules without a call


def bind(fn: Callable | None, iota: Any, index: int | None) -> Callable | None:
    """`fn(iota, index, *more)` as a callable taking `*more`. A function that the Python API
    wrapped only to drop the index (`api._self_only`) is bound to `iota` itself: the same call,
    one Python frame fewer."""
    if fn is None:
        return None
    own = getattr(fn, "iotad_self_only", None)
    if own is not None:
        return MethodType(own, iota)
    return partial(fn, iota, index)


def constant_bound(fn: Callable | None) -> float | None:
    """The float of a time bound that the Python API made from a constant (`after=0.01`), which
    `_enable` then needs not call; None for any other (a function, a parameter's name)."""
    constant = getattr(fn, "iotad_constant", None)
    if constant is None or isinstance(constant, bool):
        return None
    try:
        return float(constant)
    except (TypeError, ValueError, OverflowError):
        return None  # called as before, which reports it


def _dynamic_writes(action: Action) -> tuple:
    """(variable, index variable) of the writes `x[k]` whose element depends on state `k`."""
    if action.writes is ALL_STATE:
        return ()
    return tuple(sorted((var, key[1]) for var, key in action.writes if is_by_state(key)))


def _concrete(cells: frozenset, index: int | None) -> frozenset:
    if cells is ALL_STATE or cells == ALL_STATE:
        return ALL_STATE
    return frozenset((var, index if key == INDEX and index is not None else ANY) for var, key in cells)


class Halted(Exception):
    pass


class Engine:
    """Runs a root IOTA (a leaf or a `Composite`) under a clock and a policy.

    Trace events are dicts in the JSONL shape of docs/design.md section 5; they go to `self.trace`
    (when `record=True`) and to every sink in `sinks`.
    """

    def __init__(self, root: Any, clock: Clock | None = None, policy: Any = None, *, record: bool = True,
                 sinks: Iterable[Callable[[dict], None]] = (), max_firings_per_instant: int = 10_000,
                 deadline_tolerance: float = 0.0, reject_early_inputs: bool = True,
                 input_tolerance: float = 0.0,
                 track_dependencies: bool = True):
        self.root = root
        self.clock = clock or VirtualClock()
        self.policy = policy or Eager()
        self.trace: list[dict] = []
        self.sinks = list(sinks)
        if record:
            self.sinks.insert(0, self.trace.append)
        self.max_firings_per_instant = max_firings_per_instant
        self.deadline_tolerance = deadline_tolerance
        self.reject_early_inputs = reject_early_inputs
        # How much sooner than its switching time an input may arrive and still be accepted: in
        # a real system arrival times carry network and scheduling jitter the sender never had.
        self.input_tolerance = input_tolerance
        # False re-evaluates every precondition of a leaf after each of its firings: slower, and
        # the reference the dependency analysis is tested against.
        self.track_dependencies = track_dependencies
        self.halted = False
        self.firings = 0
        self.flat: Flat = flatten(root)
        self._heap: list = []
        self._instant = -INF
        self._instant_count = 0
        self.executing = 0.0  # the instant whose firings and inputs run now: what now() answers
        self._build()
        self._started = False

    # ---------------------------------------------------------------- building
    def _build(self) -> None:
        self.slots: dict[tuple[str, str, int | None], Slot] = {}
        self.instances: list[ActionInstance] = []
        self._by_leaf: dict[str, list[ActionInstance]] = {}
        self._readers: dict[str, dict[tuple, list[ActionInstance]]] = {}
        self.leaves = {leaf.path: leaf for leaf in self.flat.leaves}
        rank = 0
        for leaf in self.flat.leaves:
            spec = leaf.iota.iota_spec
            for name, channel in spec.channels.items():
                size = leaf.sizes[name]
                for index in ([None] if size is None else range(size)):
                    self.slots[(leaf.path, name, index)] = Slot(leaf, channel, index)
            mine: list[ActionInstance] = []
            readers: dict[tuple, list[ActionInstance]] = {}
            for action in spec.actions:
                channel = spec.channels[action.channel]
                size = leaf.sizes[action.channel]
                for index in ([None] if size is None else range(size)):
                    slot = self.slots[(leaf.path, action.channel, index)]
                    if channel.direction == "input":
                        slot.input_action = action
                        slot.do = bind(action.do, leaf.iota, index)
                        slot.dynamic = _dynamic_writes(action) if self.track_dependencies else ()
                        continue
                    instance = ActionInstance(leaf, action, index, slot, rank)
                    instance.policy = policy = self.policy_of(leaf)
                    instance.eager = policy.__class__ is Eager
                    if not self.track_dependencies:
                        instance.dynamic = ()
                    rank += 1
                    mine.append(instance)
                    for cell in instance.reads:
                        readers.setdefault(cell, []).append(instance)
            self._by_leaf[leaf.path] = mine
            self._readers[leaf.path] = readers
            self.instances += mine
        for source, target in self.flat.bindings:
            for src, dst in expand(self.flat, source, target):
                self.slots[(src.path, src.channel, src.index)].targets.append(
                    self.slots[(dst.path, dst.channel, dst.index)])
        for slot in self.slots.values():
            # an input whose type checks what the output's does: its values were checked as they left
            slot.deliveries = [(target, same_checks(slot.type, target.type)) for target in slot.targets]
        for channel_type in {id(slot.type): slot.type for slot in self.slots.values() if slot.type is not None}.values():
            channel_type.prepare()

    def policy_of(self, leaf: Leaf) -> Any:
        """The policy of `leaf`'s actions: the engine's, or the one a `PerNode` policy gives its node."""
        for_leaf = getattr(self.policy, "for_leaf", None)
        return self.policy if for_leaf is None else for_leaf(leaf.path)

    def _affected(self, leaf: Leaf, writes: frozenset, index: int | None) -> list[ActionInstance]:
        """Instances of `leaf` whose precondition reads a cell that `writes` (at `index`) may change.
        Computed once per firing action instance and cached, so it need not be fast."""
        if writes is ALL_STATE or writes == ALL_STATE or not self.track_dependencies:
            return list(self._by_leaf[leaf.path])
        if not writes:
            return []
        found: dict[int, ActionInstance] = {}
        for var, key in writes:
            own_element = key == INDEX and index is not None
            # an element chosen by state (`x[k]`) is added at firing time (`_with_dynamic`);
            # here only the readers of the whole variable
            by_state = is_by_state(key)
            for (name, where), group in self._readers[leaf.path].items():
                if name == "*" or (name == var and (where == ANY if by_state
                                                    else not own_element or where in (index, ANY))):
                    for instance in group:
                        found[instance.rank] = instance
        return [found[rank] for rank in sorted(found)]

    def _with_dynamic(self, leaf: Leaf, static: list, dynamic: tuple, before: list) -> list:
        """`static` plus the readers of the elements `x[k]` a firing wrote, with `k` taken
        before and after it (the do-block assigns `k` at most once: it indexed with one of them)."""
        readers = self._readers[leaf.path]
        extra: dict[int, ActionInstance] = {}
        for (var, source), old in zip(dynamic, before):
            for key in (old, getattr(leaf.iota, source, None)):
                try:
                    group = readers.get((var, key), ())
                except TypeError:  # an unhashable index: any element may have been written
                    group = [i for (name, _), g in readers.items() if name == var for i in g]
                for instance in group:
                    extra[instance.rank] = instance
        if not extra:
            return static
        for instance in static:
            extra[instance.rank] = instance
        return [extra[rank] for rank in sorted(extra)]

    # ---------------------------------------------------------------- running
    def now(self) -> float:
        return self.clock.now()

    def start(self) -> None:
        """Evaluate every precondition at the start time (called by `run` if needed)."""
        if self._started:
            return
        self._started = True
        now = self.clock.now()
        outer, running.engine, self.executing = running.engine, self, now
        try:
            self._evaluate_all(self.instances, now)
        finally:
            running.engine = outer

    def post(self, path: str | None, channel: str, value: Any = None, index: int | None = None,
             t: float | None = None, meta: Any = None) -> None:
        """Queue an external input. `path` None addresses the root's external channel `channel`."""
        self.clock.post((path, channel, index, value, meta), t)

    def stop(self) -> None:
        self.clock.post(STOP)

    def run(self, until: float = INF) -> list[dict]:
        """Run until virtual time `until` (inclusive), until nothing is left, or until stopped."""
        # now() in the IOTAs' code asks this engine (an engine run inside another's action puts
        # the outer one back when it returns: iotad.kernel.instant)
        outer, running.engine = running.engine, self
        try:
            self._run(until)
        finally:
            running.engine = outer
        return self.trace

    def _run(self, until: float) -> None:
        self.start()
        clock, heap = self.clock, self._heap
        if clock.__class__ is VirtualClock:
            self._run_virtual(until)
            return
        while not self.halted:
            while heap and heap[0][3].gen != heap[0][2]:
                heapq.heappop(heap)  # a dropped window
            next_fire = heap[0][0] if heap else INF
            deadline = next_fire if next_fire < until else until
            item = clock.wait(deadline)
            if item is STOP:
                break
            now = clock.now()
            if item is not None:
                self._external_input(item, now)
                continue
            if next_fire <= until and next_fire != INF:
                try:
                    self._fire_due(now)
                except Halted:
                    break
                continue
            if clock.virtual or now >= until:
                break  # the deadline was `until`, or nothing is left to happen

    def _run_virtual(self, until: float) -> None:
        """`run` under a `VirtualClock` (the class itself), its `wait`, `now` and `_fire_due` done
        inline: the same steps in the same order, three Python calls fewer per instant (tests/kernel/
        test_a_virtual_run_takes_the_same_steps_as_the_general_run_loop.py holds the two loops equal)."""
        clock, heap = self.clock, self._heap
        inbox = clock._inbox
        heappop = heapq.heappop
        while not self.halted:
            while heap and heap[0][3].gen != heap[0][2]:
                heappop(heap)  # a dropped window
            next_fire = heap[0][0] if heap else INF
            deadline = next_fire if next_fire < until else until
            if inbox and inbox[0][0] <= deadline:  # VirtualClock.wait: an input due first
                t, _, item = heappop(inbox)
                clock._now = t
                if item is STOP:
                    break
                self._external_input(item, t)
                continue
            if deadline != INF and deadline != -INF and deadline > clock._now:
                clock._now = deadline
            if next_fire <= until and next_fire != INF:
                now = clock._now
                if self._instant != now:
                    self._instant, self._instant_count = now, 0
                self.executing = now  # what now() answers in the IOTA's code
                # `_fire_due`, inline: one Python call fewer per instant, 7 % of the ping-pong
                while heap and heap[0][0] <= now:
                    fire_at, _, gen, instance = heappop(heap)
                    if instance.gen != gen or not instance.enabled:
                        continue
                    slot = instance.slot
                    earliest = slot.last + slot.switching
                    if earliest > fire_at - GRID_STEP:  # near or past its time: judged on the grid
                        earliest = plus(slot.last, slot.switching)
                    if earliest > fire_at and earliest > now:  # wait out its switching time
                        self._schedule(instance, earliest, now)
                        continue
                    self._instant_count += 1
                    if self._instant_count > self.max_firings_per_instant:
                        self._zeno(instance, now)
                        return
                    self._fire(instance, now)
                continue
            break  # the deadline was `until`, or nothing is left to happen

    def fire_due(self, count: int) -> int:
        """Fire at most `count` of the action instances due at the clock's present time, in the
        order `run` fires them; returns how many fired. Replay puts a recorded input after the
        firings that came before it at its instant this way (`deliver` then delivers it)."""
        self.start()
        outer, running.engine = running.engine, self
        try:
            return self._fire_due(self.clock.now(), count)
        except Halted:
            return 0
        finally:
            running.engine = outer

    def next_due(self) -> float:
        """When the next action instance is due (INF: none). Replay steps firing by firing with it."""
        heap = self._heap
        while heap and heap[0][3].gen != heap[0][2]:
            heapq.heappop(heap)  # a dropped window
        return heap[0][0] if heap else INF

    def next_due_action(self) -> tuple[str, str, int | None] | None:
        """(leaf path, channel, index) of the action instance `next_due` is for; None: none.
        Replay asks whether the firing a recording has next is the one the engine has due."""
        if self.next_due() == INF:
            return None
        instance = self._heap[0][3]
        return instance.leaf.path, instance.action.channel, instance.index

    def deliver(self, path: str | None, channel: str, value: Any = None, index: int | None = None) -> None:
        """An external input at the clock's present time, at once (`post` queues one instead)."""
        self.start()
        outer, running.engine = running.engine, self
        try:
            self._external_input((path, channel, index, value, None), self.clock.now())
        finally:
            running.engine = outer

    def _fire_due(self, now: float, limit: float = INF) -> int:
        self.executing = now  # what now() answers in the IOTA's code
        heap = self._heap
        fired = 0
        while fired < limit and heap and heap[0][0] <= now:
            fire_at, _, gen, instance = heapq.heappop(heap)
            if instance.gen != gen or not instance.enabled:
                continue
            slot = instance.slot
            earliest = slot.last + slot.switching
            if earliest > fire_at - GRID_STEP:  # near or past its time: judged on the grid
                earliest = plus(slot.last, slot.switching)
            if earliest > fire_at and earliest > now:
                # another action on this channel fired meanwhile: wait out its switching time
                self._schedule(instance, earliest, now)
                continue
            if self._instant != now:
                self._instant, self._instant_count = now, 0
            self._instant_count += 1
            if self._instant_count > self.max_firings_per_instant:
                self._zeno(instance, now)
                raise Halted()
            self._fire(instance, now)
            fired += 1
        return fired

    def _zeno(self, instance: ActionInstance, now: float) -> None:
        """Halt the engine: too many firings at one instant."""
        self._violation(now, instance.leaf.path, instance.action.channel, instance.index, "zeno",
                        f"more than {self.max_firings_per_instant} firings at t={now}: "
                        "a loop of actions enables itself without time passing; engine halted")
        self.halted = True

    def _fire(self, instance: ActionInstance, now: float) -> None:
        # (the instance's leaf, action and index are read only where a branch needs them: a hot path)
        slot = instance.slot
        # A window that the switching time made unreachable was reported then, and fires at the
        # earliest legal time after it: only firing later than that is the process being late.
        deadline = instance.fire_at if instance.upper < instance.fire_at < INF else instance.upper
        if now > deadline + self.deadline_tolerance:
            action = instance.action
            self._violation(now, instance.leaf.path, action.channel, instance.index, "deadline_miss",
                            f"{action.label} fired at {now:.6g}, after its deadline {deadline:.6g}")
        plain = None
        emit = True
        dynamic = instance.dynamic
        if dynamic:
            iota = instance.iota
            before = [getattr(iota, source, None) for _, source in dynamic]
        if instance.value is not None:
            try:
                plain = slot.type.checked_plain(instance.value())
            except BadValue as exc:
                action = instance.action
                self._violation(now, instance.leaf.path, action.channel, instance.index, "bad_value",
                                f"{action.label}: output value rejected: {exc}")
                emit = False
            # a fault in a spec (sys.exit() too) is a violation, not the end of the process
            except (Exception, SystemExit) as exc:  # noqa: BLE001
                self._runtime_error(now, instance, "value", exc)
                emit = False
        if instance.do is not None:
            try:
                instance.do()
            except (Exception, SystemExit) as exc:  # noqa: BLE001
                self._runtime_error(now, instance, "do", exc)
        self.firings += 1
        instance.enabled = False
        instance.gen += 1
        if emit:
            slot.last = now
            if self.sinks:  # (none: no event is built, and no call made)
                self._emit(now, instance.leaf.path, instance.action.channel, instance.index, slot.channel.direction,
                           plain)
        if dynamic:
            leaf, action, index = instance.leaf, instance.action, instance.index
            affects = instance.affects
            if affects is None:
                affects = instance.affects = self._affected(leaf, action.writes, index)
            affects = self._with_dynamic(leaf, affects, dynamic, before)
            self._evaluate_all([instance] + [other for other in affects if other is not instance], now)
        else:
            again = instance.reevaluate
            if again is None:
                affects = instance.affects
                if affects is None:
                    affects = instance.affects = self._affected(instance.leaf, instance.action.writes,
                                                                instance.index)
                again = instance.reevaluate = [instance] + [other for other in affects if other is not instance]
            self._evaluate_all(again, now)
        if emit:
            for target, checked in slot.deliveries:
                self._deliver(target, plain, now, checked)

    def _external_input(self, item: tuple, now: float) -> None:
        self.executing = now
        path, channel, index, value, meta = item
        if meta.__class__ is LaterDelivery:  # a modelled wire's delivery (iotad.kernel.wire_delay)
            if not meta.cancelled:
                for slot, checked in meta.deliveries:
                    self._deliver(slot, value, now, checked)
            return
        if path is None:
            entry = self.flat.external.get(channel)
            if entry is None or entry[0] != "input":
                self._violation(now, self.root.instance_name, channel, index, "unknown_input",
                                f"no external input channel {channel!r}")
                return
            endpoint = entry[1]
            if endpoint.index is not None and index not in (None, endpoint.index):
                # the root's channel is one member of a family: no other member is external
                self._violation(now, self.root.instance_name, channel, index, "unknown_input",
                                f"{channel} is a single channel ({endpoint}); it has no index {index}")
                return
            path, channel = endpoint.path, endpoint.channel
            if endpoint.index is not None:
                index = endpoint.index
        slot = self.slots.get((path, channel, index))
        if slot is None or slot.channel.direction != "input":
            self._violation(now, path, channel, index, "unknown_input",
                            f"{path} has no input channel {channel}{'' if index is None else f'[{index}]'}")
            return
        # a port's value that its type's checks built already (the CAN port's frames)
        self._deliver(slot, value, now, meta.__class__ is CheckedPlain and same_checks(meta.type, slot.type))

    def _deliver(self, slot: Slot, plain: Any, now: float, checked: bool = False) -> None:
        """An input event: always enabled, never blocked; rejected only if it breaks its contract.
        `checked`: `plain` is what the input's own type (or an equal one) accepted as an output
        value in `checked_plain`, so `from_checked_plain` builds the value without checking
        again what that proved (see iotad.kernel.types)."""
        leaf, channel, index = slot.leaf, slot.channel, slot.index
        # The value first: a malformed payload is a bad_value whenever it comes, so the record
        # tells it from a well-formed one that merely came too early.
        value = None
        if slot.type is not None:
            try:
                if checked:
                    # a type whose checked plain value is the value itself (an int, a bool) is not called
                    value = plain if slot.type.checked_plain_is_value else slot.type.from_checked_plain(plain)
                else:
                    value = slot.type.from_plain(plain)
                    # what the IOTA got, as its type writes it: an int of 100 bits in a float
                    # field is recorded as the float it became, which msgpack can carry (checked
                    # once, by from_plain: to_plain only writes it)
                    plain = slot.type.to_plain(value)
            except Exception as exc:  # noqa: BLE001 - BadValue, or a type's own fault on odd input
                why = exc if isinstance(exc, BadValue) else f"{type(exc).__name__}: {exc}"
                self._violation(now, leaf.path, channel.name, index, "bad_value",
                                f"input {channel.name}: {why}; rejected")
                return
        elif plain is not None:
            self._violation(now, leaf.path, channel.name, index, "bad_value",
                            f"input {channel.name} carries no value, got {plain!r}; rejected")
            return
        if now < slot.last + slot.switching + GRID_STEP and self.reject_early_inputs \
                and now < plus(slot.last, slot.switching) - self.input_tolerance:  # judged on the grid
            self._violation(now, leaf.path, channel.name, index, "switching_time",
                            f"input {channel.name} at {now:.6g} is sooner than its switching time "
                            f"{slot.switching:g} after the last one at {slot.last:.6g}; rejected")
            return
        slot.last = now
        if self.sinks:
            self._emit(now, leaf.path, channel.name, index, "input", plain)
        action = slot.input_action
        if action is None:
            return
        dynamic = slot.dynamic
        if dynamic:
            before = [getattr(leaf.iota, source, None) for _, source in dynamic]
        if slot.do is not None:
            try:
                slot.do(value)
            except (Exception, SystemExit) as exc:  # noqa: BLE001
                self._fault(now, leaf.path, channel.name, index, f"{action.label}", exc)
        affects = slot.affects
        if affects is None:
            affects = slot.affects = self._affected(leaf, action.writes, index)
        if dynamic:
            affects = self._with_dynamic(leaf, affects, dynamic, before)
        self._evaluate_all(affects, now)

    def _evaluate_all(self, instances: list[ActionInstance], now: float) -> None:
        """Each of `instances`: enable it if its precondition now holds (its window opens), drop
        its window if it no longer does. The engine's hottest loop."""
        for instance in instances:
            when = instance.when
            if when is None:
                holds = True
            else:
                try:
                    holds = when()
                except (Exception, SystemExit) as exc:  # noqa: BLE001
                    # Reported when it starts failing, not at every evaluation: how often a
                    # precondition is evaluated is the engine's business, not part of the trace.
                    if not instance.failing:
                        self._runtime_error(now, instance, "when", exc)
                        instance.failing = True
                    holds = False
                else:
                    if instance.failing:
                        instance.failing = False
            if holds:
                if not instance.enabled:
                    self._enable(instance, now)
            elif instance.enabled:
                instance.enabled = False
                instance.gen += 1  # the window is dropped; its heap entry goes stale

    def _enable(self, instance: ActionInstance, now: float) -> None:
        instance.enabled = True
        instance.gen += 1
        try:
            lower = instance.lower_bound
            if lower is None:
                lower = 0.0 if instance.after is None else float(instance.after())
            upper = instance.upper_bound
            if upper is None:
                upper = INF if instance.before is None else float(instance.before())
        except (Exception, SystemExit) as exc:  # noqa: BLE001
            self._runtime_error(now, instance, "time bound", exc)
            lower, upper = INF, INF
        else:
            if not 0.0 <= lower <= upper:  # window_ok: false for a NaN too
                action, index = instance.action, instance.index
                self._violation(now, instance.leaf.path, action.channel, index, "bad_window",
                                f"{action.label}: window [{lower:g}, {upper:g}] is empty or negative")
                lower, upper = INF, INF
        if lower == INF:
            # enabled, but with no window it cannot fire until re-enabled; and no bounds of an
            # earlier window stay behind (a checker would see that window expire)
            instance.te, instance.lower, instance.upper = now, INF, INF
            return
        # `plus` inlined for its usual cases (no delay; a delay short of 1e290; no deadline, or
        # one equal to the delay, as `after=d` makes it): this is a hot path
        if lower == 0:
            earliest = now
        else:
            later = now + lower
            if -1e290 < later < 1e290:  # (the grid's product cannot overflow: `plus` without the call)
                on_grid = round(later * TIME_GRID) / TIME_GRID
                earliest = on_grid if on_grid >= now else now
            else:
                earliest = plus(now, lower)
        instance.te, instance.lower = now, earliest
        instance.upper = INF if upper == INF else earliest if upper == lower else plus(now, upper)
        slot = instance.slot
        if slot.last + slot.switching > earliest:
            earliest = max(earliest, plus(slot.last, slot.switching))
        if earliest <= instance.upper and instance.eager:
            instance.fire_at = earliest  # `_schedule`'s usual case, without the call
            heapq.heappush(self._heap, (earliest, instance.rank, instance.gen, instance))
            return
        self._schedule(instance, earliest, now)

    def _schedule(self, instance: ActionInstance, earliest: float, now: float) -> None:
        if earliest > instance.upper:
            action = instance.action
            self._violation(now, instance.leaf.path, action.channel, instance.index, "unreachable_window",
                            f"{action.label}: switching time {instance.slot.switching:g} puts its earliest "
                            f"firing at {earliest:.6g}, past its window's end {instance.upper:.6g}")
            fire_at = earliest
        elif instance.eager:
            fire_at = earliest  # Eager.choose, without the call
        else:
            fire_at = instance.policy.choose(earliest, instance.upper)
        instance.fire_at = fire_at
        heapq.heappush(self._heap, (fire_at, instance.rank, instance.gen, instance))

    def fire_instance(self, instance: ActionInstance, now: float) -> None:
        """Fire one enabled action instance at `now`, the time chosen from outside the policy:
        the trace checker (iotad.recording.conformance) replays a recorded firing this way."""
        outer, running.engine, self.executing = running.engine, self, now
        try:
            self._fire(instance, now)
        finally:
            running.engine = outer

    # ---------------------------------------------------------------- events
    def _emit(self, t: float, path: str, channel: str, index: int | None, kind: str, value: Any) -> None:
        sinks = self.sinks
        if sinks:  # (none: the event is not built)
            event = {"t": t, "iota": path, "action": channel, "index": index, "kind": kind, "value": value}
            for sink in sinks:
                sink(event)

    def _violation(self, t: float, path: str, channel: str, index: int | None, code: str, message: str,
                   fields: dict | None = None) -> None:
        self._emit(t, path, channel, index, "violation", {"violation": code, "message": message, **(fields or {})})

    def _runtime_error(self, t: float, instance: ActionInstance, part: str, exc: Exception) -> None:
        self._fault(t, instance.leaf.path, instance.action.channel, instance.index,
                    f"{instance.action.label} ({part})", exc)

    def _fault(self, t: float, path: str, channel: str, index: int | None, label: str, exc: BaseException) -> None:
        """An exception of the node's own code: a runtime_error violation naming the file and line
        that raised, with the traceback in its value (the recording keeps both)."""
        from iotad.kernel.code_fault import NodeViolation, fault_text, fault_traceback, fault_where

        if isinstance(exc, NodeViolation):  # the node found it and says what it is
            self._violation(t, path, channel, index, exc.code, str(exc), exc.fields)
            return
        self._emit(t, path, channel, index, "violation",
                   {"violation": "runtime_error", "message": f"{label}: {fault_text(exc)}",
                    "where": fault_where(exc) or "", "traceback": fault_traceback(exc)})

    # ---------------------------------------------------------------- views
    def external_trace(self, events: Iterable[dict] | None = None) -> list[dict]:
        """The root's external behaviour: events on its external channels, named as the root names them."""
        # keyed by index too: a root channel may be one member of a component's family, which
        # then appears as a plain channel (index None) and the other members stay hidden
        names = {(endpoint.path, endpoint.channel, endpoint.index): name
                 for name, (_, endpoint) in self.flat.external.items()}
        out = []
        for event in self.trace if events is None else events:
            if event["kind"] not in ("input", "output"):
                continue
            name = names.get((event["iota"], event["action"], None))
            if name is not None:
                out.append(dict(event, iota=self.root.instance_name, action=name))
                continue
            name = names.get((event["iota"], event["action"], event.get("index")))
            if name is not None:
                out.append(dict(event, iota=self.root.instance_name, action=name, index=None))
        return out

    def iota(self, path: str) -> Any:
        """The instance at `path`, to read its state in tests and tools."""
        return self.leaves[path].iota

    def endpoint(self, path: str, channel: str, index: int | None = None) -> Endpoint:
        return Endpoint(path, channel, index)
