"""Deliveries over a modelled wire: an output's value handed to the inputs it is bound to at a
later instant, with no firing of the output (a CAN bus's frames, each at its wire-end time).

A bus that computes the frames of one instant in one firing (`iotad.can.burst_bus`) still hands
each frame to every receiver at the instant the frame ends on the wire: `deliver_later` queues
one input per bound receiver on the running engine's clock at that time, as an external input
would be queued, and the receivers take it there as an input event of their own (recorded as
such). The output itself fires no event: the firing that computed the frames records them.
A later arbitration can move a frame that has not started yet, so a queued delivery can be
cancelled (`LaterDelivery.cancel`) and queued again at its new time; a cancelled one is never delivered.
Outside a running engine (a lone node under `iotad check`) or with nothing bound, nothing is queued.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.instant import running


class LaterDelivery:
    """A value queued by `deliver_later` for the inputs bound to one or more outputs (the engine's
    `_external_input` knows it by its class): (input slot, checked) pairs, delivered in order at
    one instant; `cancel()` withdraws it."""

    __slots__ = ("deliveries", "cancelled")

    def __init__(self, deliveries: list) -> None:
        self.deliveries = deliveries
        self.cancelled = False

    def cancel(self) -> None:
        self.cancelled = True


def deliver_later(iota: Any, channel: str, indices: tuple, value: Any, t: float) -> LaterDelivery | None:
    """Queue `value`, sent on `iota`'s outputs `channel[k]` for k in `indices` (`(None,)`: a plain
    channel), for every input bound to them, at time `t` (not before the present), as one item.
    None when no engine runs this IOTA or nothing is bound."""
    engine = running.engine
    if engine is None:
        return None
    routes = engine.__dict__.get("_later_routes")
    if routes is None:
        routes = engine.__dict__["_later_routes"] = {}
    key = (id(iota), channel, indices)
    route = routes.get(key)
    if route is None:
        route = routes[key] = _route(engine, iota, channel, indices)
    output_type, deliveries = route
    if not deliveries:
        return None
    later = LaterDelivery(deliveries)
    engine.clock.post((None, None, None, output_type.checked_plain(value) if output_type is not None else None,
                       later), t)
    return later


def _route(engine: Any, iota: Any, channel: str, indices: tuple) -> tuple:
    for path, leaf in engine.leaves.items():
        if leaf.iota is iota:
            slots = [engine.slots[(path, channel, index)] for index in indices]
            return slots[0].type, [delivery for slot in slots for delivery in slot.deliveries]
    return None, []
