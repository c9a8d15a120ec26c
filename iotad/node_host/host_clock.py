"""The node host's clock: a `RealClock` whose wait loop, run on the engine thread, also decodes
raw zenoh payloads, beats the application heartbeat and flushes the buffered trace.

Doing that work on the engine thread rather than on zenoh's callback threads is the point: a
heartbeat then proves that the engine loop itself is alive (not only the process), a malformed
payload is reported in order with the node's other events, and only one thread ever publishes
on `@trace`. Trace events are flushed `trace_period` after the first of them was buffered (or
when the buffer is full, or at a heartbeat, or at the stop), never in the middle of a step: an
output is never delayed behind the trace of the input that caused it, and a recorder is woken
once per period and node, not once per event (on a machine with few cores its wake-ups are what
recording costs the nodes). A node killed with SIGKILL loses at most that period of its trace.

The inbox is bounded (`input_queue` inputs; None: unbounded): a flood fills it, and the zenoh
callback then drops the input and counts it per channel, so that memory stays bounded before the
engine can even look at the inputs (a switching-time check refuses them only once taken out).
The engine thread reports the count as one `input_overflow` violation per channel (at most one
per `overflow_period`, and at the stop): how many inputs were dropped and between which times.
What fits in the queue is served as usual; the stop and restart notices are never dropped.

On a host other than the hub's, its launcher measures the host's clock against the hub's during
the run and tells its nodes the hub's origin on this host's clock again (`follow`): the clock
then reads its raw time plus a `Correction` (iotad/node_host/clock_correction.py), stepped forward or
slewed back, never run backwards.
"""
from __future__ import annotations

import math
import queue
import threading
from typing import Any, Callable

from iotad.node_host import wire
from iotad.node_host.clock_correction import Correction
from iotad.kernel.clock import RealClock
from iotad.kernel.engine import STOP


class RawInput:
    """A sample as a zenoh callback hands it over: undecoded, so the callback stays short."""

    __slots__ = ("name", "index", "payload", "attachment", "key")

    def __init__(self, name: str, index: int | None, payload: bytes, attachment: bytes | None,
                 key: str | None = None):
        self.name, self.index, self.payload, self.attachment = name, index, payload, attachment
        self.key = key  # the key it arrived on (the node's own input key, or a bound output's)


class DecodedInput(RawInput):
    """An input a port hands over already as its plain value (`payload`): the CAN port's frames,
    which no wire format carried, go to the engine without a msgpack round trip. `checked`: a
    `CheckedPlain` when the port built the value with its type's checks (the engine does not check
    it again)."""

    __slots__ = ("checked",)

    def __init__(self, name: str, index: int | None, payload: Any, key: str | None = None, checked: Any = None):
        super().__init__(name, index, payload, None, key)
        self.checked = checked


class HostClock(RealClock):
    TRACE_BATCH = 64  # flush the trace at least this often under a flood of inputs

    def __init__(self, time_unit: float = 1.0, origin: float | None = None, *,
                 heartbeat_period: float = 0.5,
                 on_heartbeat: Callable[[float, int], None] = lambda t, backlog: None,
                 on_malformed: Callable[[float, RawInput, str], None] = lambda t, raw, message: None,
                 flush: Callable[[], None] = lambda: None, pending: Callable[[], int] = lambda: 0,
                 trace_period: float = 0.0, input_queue: int | None = None,
                 on_overflow: Callable[[float, str, int | None, int, float, float], None] | None = None):
        super().__init__(time_unit, origin)
        if input_queue is not None and input_queue < 1:
            raise ValueError(f"input_queue must be at least 1, got {input_queue!r}")
        self.input_queue = input_queue
        # (channel, index) -> [dropped, first drop t, last drop t]; written by zenoh callbacks
        self._dropped: dict[tuple[str, int | None], list] = {}
        self._drop_lock = threading.Lock()
        self.dropped_total = 0
        self._on_overflow = on_overflow or (lambda t, name, index, count, first, last: None)
        self._overflow_period = heartbeat_period / time_unit  # report drops at most this often
        self._next_overflow = -math.inf
        self._trace_period = trace_period / time_unit  # in clock units; 0: flush before blocking
        self._trace_due = math.inf  # when the oldest buffered trace event must be out
        self._inbox = queue.SimpleQueue()  # C-implemented: cheaper put/get than queue.Queue
        self._period = heartbeat_period / time_unit  # in clock units
        self._next_beat = -math.inf
        self._on_heartbeat, self._on_malformed = on_heartbeat, on_malformed
        self._flush, self._pending = flush, pending
        # The input the engine is handling now (set when `wait` hands it over, cleared at the next
        # `wait`): the host adds its key and the sender's attachment to the input's trace event.
        self.current_input: RawInput | None = None
        self.correction: Correction | None = None  # made by the first `follow`: none on the hub's host

    def now(self) -> float:
        raw = RealClock.now(self)
        correction = self.correction
        return raw if correction is None else raw + correction.at(raw)

    def follow(self, origin: float) -> float:
        """The launcher measured this host's clock again: `origin` is the hub's origin on it now
        (wall seconds). The clock moves onto it, forward at once, back by slewing; returns the
        step taken now, in clock units (0 while slewing)."""
        if self.correction is None:
            self.correction = Correction()
        return self.correction.aim((self.origin_wall - origin) / self.time_unit, RealClock.now(self))

    def post(self, item: Any, t: float | None = None) -> None:
        """Queue an input (a zenoh callback's or the CAN port's `RawInput`); when the inbox holds
        `input_queue` items already, drop it and count it instead."""
        if self.input_queue is not None and item.__class__ is RawInput and self._inbox.qsize() >= self.input_queue:
            now = self.now()
            with self._drop_lock:
                entry = self._dropped.get((item.name, item.index))
                if entry is None:
                    self._dropped[(item.name, item.index)] = [1, now, now]
                else:
                    entry[0] += 1
                    entry[2] = now
            return
        self._inbox.put(item)

    def post_always(self, item: Any) -> None:
        """Queue an item past the bound: stop requests, restart notices (rare, and never lost)."""
        self._inbox.put(item)

    def report_overflow(self) -> None:
        """Hand the drops counted since the last report to `on_overflow`, one call per channel
        (engine thread)."""
        with self._drop_lock:
            dropped, self._dropped = self._dropped, {}
        for (name, index), (count, first, last) in dropped.items():
            self.dropped_total += count
            self._on_overflow(self.now(), name, index, count, first, last)

    def backlog(self) -> int:
        return self._inbox.qsize()

    def wait(self, deadline: float) -> Any | None:
        self.current_input = None
        inbox = self._inbox
        while True:
            now = self.now()
            if self._dropped and now >= self._next_overflow:
                self._next_overflow = now + self._overflow_period
                self.report_overflow()
            if now >= self._next_beat:
                self._flush_trace()
                self._on_heartbeat(now, inbox.qsize())
                # skip missed beats rather than bursting them after a stall
                self._next_beat = max(self._next_beat + self._period, now + self._period * 0.5)
            pending = self._pending()
            if pending:
                if self._trace_due == math.inf:
                    self._trace_due = now + self._trace_period
                elif pending >= self.TRACE_BATCH or (self._trace_period and now >= self._trace_due + self._trace_period):
                    self._flush_trace()  # a flood of inputs or of due firings: do not wait to block
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                if deadline <= now:
                    return None  # a firing is due: its output goes out before any trace
                if now >= self._trace_due:
                    self._flush_trace()  # due, and about to block: now is the moment
                limit = min(deadline, self._next_beat, self._trace_due)
                timeout = (limit - self.now()) * self.time_unit
                try:
                    item = inbox.get(timeout=timeout) if timeout > 0 else inbox.get_nowait()
                except queue.Empty:
                    if self.now() >= deadline:
                        return None
                    continue  # woke for a heartbeat or a trace flush
            if item.__class__ is RawInput:
                item = self._decode(item)
                if item is None:
                    continue
            elif item.__class__ is DecodedInput:
                self.current_input = item
                item = (None, item.name, item.index, item.payload, item.checked)
            elif item is STOP:
                self.report_overflow()
                self._flush_trace()
            return item

    def _flush_trace(self) -> None:
        self._trace_due = math.inf
        self._flush()

    def _decode(self, raw: RawInput) -> tuple | None:
        try:
            value = wire.decode(raw.payload)
        except wire.WireError as exc:
            self._on_malformed(self.now(), raw, str(exc))
            return None
        self.current_input = raw
        # the engine's item: (path None = root's external channel, channel, index, value, meta)
        return (None, raw.name, raw.index, value, raw.attachment)
