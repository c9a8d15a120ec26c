"""Sweep metrics of a motion scheduler's run (`[sweep] metrics` of examples/figure2.toml and
examples/mdl_arm.toml): how many requests it committed, aborted and rejected, from the acks the
scheduler sent; how many requests it got and left unanswered; and how many answers to its
highest-priority requester were COMMIT and how many were not (the goals of both systems:
docs/stress.md)."""
from __future__ import annotations

from iotad.recording.timeline_plot import find_scheduler, timeline


def ack_metrics(recording) -> dict:
    scheduler = find_scheduler(recording)
    acks = timeline(recording, scheduler)["acks"]
    metrics = {name.lower() + "s": sum(1 for _, _, ack in acks if ack == name) for name in ("COMMIT", "ABORT", "REJECT")}
    requests = [(0 if e.get("index") is None else e["index"], e.get("value") or {})
                for e in recording.trace(scheduler) if e["kind"] == "input" and e["action"] == "req"]
    priority = {index: value.get("priority", 0) for index, value in requests if isinstance(value, dict)}
    top = max(priority, key=lambda index: (priority[index], index)) if priority else None
    metrics["requests"] = len(requests)
    metrics["unanswered"] = len(requests) - len(acks)
    # the highest-priority requester's answers: a request of its still running at the end is neither
    metrics["top_committed"] = sum(1 for index, _, ack in acks if index == top and ack == "COMMIT")
    metrics["top_refused"] = sum(1 for index, _, ack in acks if index == top and ack != "COMMIT")
    return metrics
