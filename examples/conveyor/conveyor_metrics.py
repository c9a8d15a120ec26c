"""The conveyor arm's sweep metrics (`[sweep] metrics` of examples/conveyor.toml): objects placed
in the bin, missed and dropped, as the world counted them, and how often the scheduler took the
arm from one requester for another (preemptions)."""
from __future__ import annotations

from sim.worlds.conveyor_plot import conveyor_data
from iotad.recording.timeline_plot import timeline


def conveyor_metrics(recording) -> dict:
    data = conveyor_data(recording)
    final = data["tally"][-1][1]
    holds = timeline(recording, data["scheduler"])["holds"]
    return {"spawned": final["spawned"], "placed": final["placed"], "missed": final["missed"],
            "dropped": final["dropped"], "preemptions": sum(1 for *_, how in holds if how == "pre-empted")}
