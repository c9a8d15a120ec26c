"""Buggy's sweep metrics (`[sweep] metrics` of examples/buggy.toml): food eaten, wall bumps,
seconds in each basic behaviour, and mean hunger and fear, from one run's recording."""
from __future__ import annotations

from sim.worlds.buggy_plot import buggy_data


def buggy_metrics(recording) -> dict:
    data = buggy_data(recording)
    mood, path = data["mood"], data["path"]
    # the pose counts bumps from 0 in each world: the counts each world ended with, summed
    bumps, last = 0, 0
    cuts = sorted(data["restarts"])
    for t, pose in path:
        while cuts and t >= cuts[0]:
            cuts.pop(0)
            bumps, last = bumps + last, 0
        last = pose.get("bumps", 0)
    seconds = {"WANDER": 0.0, "FOLLOW": 0.0, "EAT": 0.0, "AVOID": 0.0}
    hunger = fear = 0.0
    for (t0, m), (t1, _) in zip(mood, mood[1:]):  # each mood holds until the next: time-weighted
        seconds[m.get("doing", "WANDER")] = seconds.get(m.get("doing", "WANDER"), 0.0) + (t1 - t0)
        hunger += m.get("hunger", 0.0) * (t1 - t0)
        fear += m.get("fear", 0.0) * (t1 - t0)
    span = mood[-1][0] - mood[0][0] if len(mood) > 1 else 0.0
    return {"food_eaten": len(data["arena"]["eaten"]), "wall_bumps": bumps + last,
            **{f"{doing.lower()}_s": round(s, 6) for doing, s in seconds.items()},
            "mean_hunger": round(hunger / span, 6) if span else 0.0,
            "mean_fear": round(fear / span, 6) if span else 0.0}
