"""A host's clock measured against the hub's, NTP-style: repeated round trips, each giving an
interval that must hold the true offset; the offset is the middle of what all of them agree on,
and its bound half the width of that. Switching times and windows of nodes on several hosts are
judged on one timeline only if each host's clock is corrected by this offset.

One round trip: the host notes `sent` on its clock, the hub answers with the times it received
and replied on its own clock, the host notes `received`. With offset = hub clock - host clock,
    offset = ((hub_received - sent) + (hub_replied - received)) / 2
is off by at most half the round trip's time on the wire, (received - sent) - (hub_replied -
hub_received), whichever way the delay was split. A short round trip is a tight interval; a
round trip delayed by load is a wide one, and the intersection ignores it by itself.

The hub answers on `clock_key(system)` (a zenoh queryable, `ClockServer`); a host measures with
`measure(session, system)`. The recording keeps each measurement (offset, bound, when), and
`iotad check` widens a window by the bound and no more."""
from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass
from typing import Callable, Sequence

import msgpack

from iotad.kernel.clock import wall

DEFAULT_LIMIT = 1e-3  # seconds: a host whose offset is known no better than this is a violation


PREFIX = "iota"  # the node host's wire.PREFIX, which sits above this module (a test holds them equal)


def clock_key(system: str) -> str:
    """Where the hub answers clock queries (an '@' chunk: `iota/S/**` never matches it)."""
    return f"{PREFIX}/{system}/@clock"


@dataclass(frozen=True)
class Sample:
    """One round trip: the host's clock at `sent` and `received`, the hub's in between."""
    sent: float
    hub_received: float
    hub_replied: float
    received: float

    @property
    def offset(self) -> float:
        return ((self.hub_received - self.sent) + (self.hub_replied - self.received)) / 2

    @property
    def delay(self) -> float:
        """Time on the wire, there and back (the hub's own time in between left out)."""
        return max(0.0, (self.received - self.sent) - (self.hub_replied - self.hub_received))


@dataclass(frozen=True)
class ClockOffset:
    """hub clock = host clock + `offset`, within +-`bound` (seconds), from `samples` round trips."""
    offset: float
    bound: float
    samples: int
    best_delay: float

    def correct(self, host_time: float) -> float:
        """A time on this host's clock, on the hub's."""
        return host_time + self.offset

    def problem(self, limit: float = DEFAULT_LIMIT) -> str:
        """Why this measurement is not good enough ("" when it is): its bound is past `limit`."""
        if self.bound > limit:
            return (f"clock offset to the hub {self.offset * 1e3:+.3f} ms is known only within "
                    f"+-{self.bound * 1e3:.3f} ms, more than the allowed {limit * 1e3:.3f} ms")
        return ""

    def as_plain(self) -> dict:
        return {"offset": self.offset, "bound": self.bound, "samples": self.samples,
                "best_delay": self.best_delay}


class ClockError(Exception):
    """No usable round trip to the hub's clock."""


def estimate(samples: Sequence[Sample]) -> ClockOffset:
    """The offset all `samples` agree on. Each sample's interval [offset - delay/2, offset +
    delay/2] holds the true offset; their intersection is the tightest statement. If they do not
    intersect (a clock stepped or drifted during the measurement), the shortest round trip alone
    is taken, as NTP does."""
    usable = [sample for sample in samples if all(map(math.isfinite, (sample.sent, sample.hub_received,
                                                                      sample.hub_replied, sample.received)))
              and sample.received >= sample.sent]
    if not usable:
        raise ClockError("no usable round trip to the hub's clock")
    best = min(usable, key=lambda sample: sample.delay)
    low = max(sample.offset - sample.delay / 2 for sample in usable)
    high = min(sample.offset + sample.delay / 2 for sample in usable)
    if low <= high:
        return ClockOffset((low + high) / 2, (high - low) / 2, len(usable), best.delay)
    return ClockOffset(best.offset, best.delay / 2, len(usable), best.delay)


class ClockServer:
    """The hub's side: answers every clock query with the times it received and replied, on
    `clock` (the wall clock by default). Close it (or use `with`)."""

    def __init__(self, session, system: str, clock: Callable[[], float] = wall):
        self._clock = clock
        self._queryable = session.declare_queryable(clock_key(system), self._answer)

    def _answer(self, query) -> None:
        received = self._clock()
        # the query's token is echoed, so that the host takes this answer for that query alone
        token = query.payload.to_bytes() if query.payload is not None else b""
        query.reply(query.key_expr, msgpack.packb([received, self._clock(), token]))

    def close(self) -> None:
        self._queryable.undeclare()

    undeclare = close  # as the zenoh entities a launcher undeclares at its end

    def __enter__(self) -> "ClockServer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _RoundTrip:
    """One round trip's own reply: the first answer that echoes its token. A reply that comes late
    (to a query of an earlier round, answered twice over two routes or after the round gave up)
    belongs to that round, never to a later one. When the rounds shared one reply slot, such a
    reply was taken as the next round's, its hub times paired with that round's sending: after a
    partition of arm healed, a reading of two round trips said -9.275 ms +-0.147 ms on a machine
    whose hosts share one clock (+0.065 ms ten seconds before), and arm's nodes ran 9 ms off the
    hub's timeline for 27 s."""

    def __init__(self, clock: Callable[[], float], token: bytes):
        self.clock, self.token = clock, token
        self.answer: tuple[float, float, float] | None = None  # received (host), hub_received, hub_replied
        self.done = threading.Event()

    def on_reply(self, reply) -> None:
        received = self.clock()
        if self.answer is not None:
            return
        try:
            hub_received, hub_replied, token = msgpack.unpackb(reply.ok.payload.to_bytes())
            if token != self.token:
                return  # another query's answer
            self.answer = (received, float(hub_received), float(hub_replied))
        except (AttributeError, ValueError, TypeError, msgpack.UnpackException):
            return  # an error reply or a stranger's answer on the key: not a sample
        self.done.set()


def measure(session, system: str, rounds: int = 16, clock: Callable[[], float] = wall,
            timeout: float = 1.0, stop: threading.Event | None = None) -> ClockOffset:
    """This host's offset to the hub of `system`: `rounds` round trips, one at a time. Raises
    `ClockError` when the hub answers none of them; gives up after three unanswered in a row
    (a hub that is gone does not hold a launcher for `rounds` seconds), or once `stop` is set."""
    samples: list[Sample] = []
    unanswered = 0
    for number in range(rounds):
        if unanswered >= 3 or (stop is not None and stop.is_set()):
            break
        trip = _RoundTrip(clock, os.urandom(8) + number.to_bytes(2, "big"))
        sent = clock()
        session.get(clock_key(system), trip.on_reply, payload=trip.token, timeout=timeout)
        if not trip.done.wait(timeout) or trip.answer is None:
            unanswered += 1
            continue
        unanswered = 0
        received, hub_received, hub_replied = trip.answer
        samples.append(Sample(sent, hub_received, hub_replied, received))
    if not samples:
        raise ClockError(f"the hub of system {system!r} answered no clock query on {clock_key(system)} "
                         f"in {rounds} tries of {timeout:g} s")
    return estimate(samples)
