"""The node host's clock: a `RealClock` whose wait loop, run on the engine thread, also decodes
raw zenoh payloads, beats the application heartbeat and flushes the buffered trace.

Doing that work on the engine thread rather than on zenoh's callback threads is the point: a
heartbeat then proves that the engine loop itself is alive (not only the process), a malformed
payload is reported in order with the node's other events, and only one thread ever publishes
on `@trace`. Trace events are flushed only when the engine is about to block (or the buffer is
full), so an output is never delayed behind the trace of the input that caused it.
"""
from __future__ import annotations

import math
import queue
from typing import Any, Callable

from . import wire
from .clock import RealClock
from .engine import STOP


class RawInput:
    """A sample as a zenoh callback hands it over: undecoded, so the callback stays short."""

    __slots__ = ("name", "index", "payload", "attachment")

    def __init__(self, name: str, index: int | None, payload: bytes, attachment: bytes | None):
        self.name, self.index, self.payload, self.attachment = name, index, payload, attachment


class HostClock(RealClock):
    TRACE_BATCH = 64  # flush the trace at least this often under a flood of inputs

    def __init__(self, time_unit: float = 1.0, origin: float | None = None, *,
                 heartbeat_period: float = 0.5,
                 on_heartbeat: Callable[[float, int], None] = lambda t, backlog: None,
                 on_malformed: Callable[[float, RawInput, str], None] = lambda t, raw, message: None,
                 flush: Callable[[], None] = lambda: None, pending: Callable[[], int] = lambda: 0):
        super().__init__(time_unit, origin)
        self._inbox = queue.SimpleQueue()  # C-implemented: cheaper put/get than queue.Queue
        self._period = heartbeat_period / time_unit  # in clock units
        self._next_beat = -math.inf
        self._on_heartbeat, self._on_malformed = on_heartbeat, on_malformed
        self._flush, self._pending = flush, pending

    def post(self, item: Any, t: float | None = None) -> None:
        self._inbox.put(item)

    def backlog(self) -> int:
        return self._inbox.qsize()

    def wait(self, deadline: float) -> Any | None:
        inbox = self._inbox
        while True:
            now = self.now()
            if now >= self._next_beat:
                self._flush()
                self._on_heartbeat(now, inbox.qsize())
                # skip missed beats rather than bursting them after a stall
                self._next_beat = max(self._next_beat + self._period, now + self._period * 0.5)
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                limit = deadline if deadline < self._next_beat else self._next_beat
                timeout = (limit - self.now()) * self.time_unit
                if timeout > 0:
                    # About to block: publish the trace of the last steps now, not before an
                    # output that is due at once (the engine calls wait(now) before firing it).
                    if self._pending():
                        self._flush()
                        timeout = (limit - self.now()) * self.time_unit
                    try:
                        item = inbox.get(timeout=timeout) if timeout > 0 else inbox.get_nowait()
                    except queue.Empty:
                        item = None
                else:
                    item = None
                if item is None:
                    if self.now() >= deadline:
                        return None
                    continue  # woke for a heartbeat
            else:
                if self._pending() >= self.TRACE_BATCH:
                    self._flush()
            if item.__class__ is RawInput:
                item = self._decode(item)
                if item is None:
                    continue
            elif item is STOP:
                self._flush()
            return item

    def _decode(self, raw: RawInput) -> tuple | None:
        try:
            value = wire.decode(raw.payload)
        except wire.WireError as exc:
            self._on_malformed(self.now(), raw, str(exc))
            return None
        # the engine's item: (path None = root's external channel, channel, index, value, meta)
        return (None, raw.name, raw.index, value, raw.attachment)
