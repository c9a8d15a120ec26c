"""The window a recorded firing of a virtual run fired in: the run made again, in this process,
under the same policy (a virtual run is deterministic for its policy and seed), up to the
instant of that firing, where the engine holds the action's window (`iotad stress` names it)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from iotad.kernel.api import close_iotas


@dataclass(frozen=True)
class Window:
    """The action instance's window when it fired: enabled at `enabled`, allowed from `lower`
    to `upper` (its switching time included in `earliest`), chosen by the policy at `fire_at`."""

    enabled: float
    lower: float
    upper: float
    earliest: float
    fire_at: float

    def line(self, time_unit: float = 1.0) -> str:
        upper = "inf" if math.isinf(self.upper) else f"{self.upper * time_unit:.4f}"
        where = ("at its window's end" if math.isclose(self.fire_at, self.upper, abs_tol=1e-9) else
                 "at its earliest" if math.isclose(self.fire_at, self.earliest, abs_tol=1e-9) else
                 f"{(self.fire_at - self.earliest) / (self.upper - self.earliest):.0%} into it"
                 if math.isfinite(self.upper) and self.upper > self.earliest else "")
        return (f"window [{self.lower * time_unit:.4f}, {upper}] s (enabled at {self.enabled * time_unit:.4f} s"
                + (f", its switching time allows it from {self.earliest * time_unit:.4f} s" if self.earliest > self.lower
                   else "") + f"), fired {where}".rstrip(", "))


def firing_window(system: Any, policy: Any, iota: str, action: str, index: Any, t: float) -> Window | None:
    """The window of the firing of `iota`'s `action` (at `index`) at engine time `t` in the run
    of `system` under `policy` (a fresh policy object, as the run had at its start); None when
    the run made again has no such firing due at `t`."""
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    from iotad.launcher.system.in_process import compose

    root = compose(system)
    engine = Engine(root, VirtualClock(), policy, record=False)
    try:
        paths = {iota, f"{root.instance_name}/{iota}"}  # a recording names a node's leaves under the system
        instances = [i for i in engine.instances
                     if i.leaf.path in paths and i.action.channel == action and i.index == index]
        if not instances:
            return None
        before = math.nextafter(t, -math.inf)
        if before > 0:
            engine.run(before)  # every firing before `t`, none at it
        engine.start()
        engine.clock._now = max(engine.clock._now, t)  # (a VirtualClock: the instant of the firing)
        for _ in range(engine.max_firings_per_instant):
            for instance in instances:
                if instance.enabled and math.isclose(instance.fire_at, t, rel_tol=0, abs_tol=1e-9):
                    slot = instance.slot
                    earliest = max(instance.lower, slot.last + slot.switching)
                    return Window(instance.te, instance.lower, instance.upper, earliest, instance.fire_at)
            if engine.next_due() > t or not engine.fire_due(1):  # the firings at `t` before it
                return None
        return None
    finally:
        close_iotas(leaf.iota for leaf in engine.leaves.values())
