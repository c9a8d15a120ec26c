"""Deliveries over a modelled wire: an output's value handed to the inputs it is bound to at a
later instant, with no firing of the output (a CAN bus's frames, each at its wire-end time).

A bus that computes the frames of one instant in one firing (`iotad.can.burst_bus`) still hands
each frame to every receiver at the instant the frame ends on the wire: `deliver_later` queues
one input per bound receiver on the running engine's clock at that time, as an external input
would be queued, and the receivers take it there as an input event of their own (recorded as
such). The output itself fires no event: the firing that computed the frames records them.
A later arbitration can move a frame that has not started yet, so a queued delivery can be
cancelled (`Later.cancel`) and queued again at its new time; a cancelled one is never delivered.
Outside a running engine (a lone node under `iotad check`) or with nothing bound, nothing is queued.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.instant import running


class Later:
    """The deliveries of one value queued by `deliver_later`; `cancel()` withdraws them all."""

    __slots__ = ("cancelled",)

    def __init__(self) -> None:
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True


class LaterDelivery:
    """One queued delivery (the engine's `_external_input` knows it by its class): the input
    slot it goes to, whether its value is what that input's type accepted, and its `Later`."""

    __slots__ = ("slot", "checked", "later")

    def __init__(self, slot: Any, checked: bool, later: Later) -> None:
        self.slot, self.checked, self.later = slot, checked, later


def deliver_later(iota: Any, channel: str, index: int | None, value: Any, t: float,
                  later: Later | None = None) -> Later | None:
    """Queue `value`, sent on `iota`'s output `channel[index]`, for every input bound to it, at
    time `t` (not before the present), under `later` (a new one if None: cancelling it withdraws
    every delivery queued under it). None when no engine runs this IOTA or nothing is bound."""
    engine = running.engine
    if engine is None:
        return None
    routes = engine.__dict__.get("_later_routes")
    if routes is None:
        routes = engine.__dict__["_later_routes"] = {}
    key = (id(iota), channel, index)
    route = routes.get(key)
    if route is None:
        route = routes[key] = _route(engine, iota, channel, index)
    slot, deliveries = route
    if not deliveries:
        return None
    plain = slot.type.checked_plain(value) if slot.type is not None else None
    if later is None:
        later = Later()
    post = engine.clock.post
    for target, checked in deliveries:
        post((None, None, None, plain, LaterDelivery(target, checked, later)), t)
    return later


def _route(engine: Any, iota: Any, channel: str, index: int | None) -> tuple:
    for path, leaf in engine.leaves.items():
        if leaf.iota is iota:
            slot = engine.slots[(path, channel, index)]
            return slot, list(slot.deliveries)
    return None, []
