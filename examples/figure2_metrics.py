"""Sweep metrics of a motion scheduler's run (`[sweep] metrics` of examples/figure2.toml): how
many requests it committed, aborted and rejected, from the acks the scheduler sent."""
from __future__ import annotations

from iotad.recording.timeline_plot import find_scheduler, timeline


def ack_metrics(recording) -> dict:
    acks = timeline(recording, find_scheduler(recording))["acks"]
    return {name.lower() + "s": sum(1 for _, _, ack in acks if ack == name) for name in ("COMMIT", "ABORT", "REJECT")}
