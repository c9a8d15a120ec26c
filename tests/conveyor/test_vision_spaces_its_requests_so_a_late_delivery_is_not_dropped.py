"""Vision spaces its requests by more than req's switching time, so that the scheduler, which
measures that time between arrivals, never drops one delivered a little sooner than the one
before. The conveyor split over three hosts (vision on one, the scheduler on another) lost two
requests so on a loaded machine: look-7-16 went out at 65.7855 s and arrived at 65.7895 (4 ms),
look--1-17 went out 1.0002 s later, at 66.7857, and arrived at 66.7867 (1 ms): 0.9972 s after
the one before, inside the switching time of 1 s. The scheduler recorded a switching_time
violation and dropped it; no ack ever came for it, vision kept it for live, and the arm went on
tracking a target planning had given up.

Vision alone in virtual time makes the requests from the recording's goals (their times
shifted); the conveyor's scheduler then takes them with the recording's delivery delays."""
import pytest

from conveyor_variant import FOLDER
from conveyor_types import LOOK_GOAL, REQ_SWITCHING
from iotad import Engine
from iotad.esprit import load_iota
from vision import VisionControl

# the recording's goals to vision (s; 64.4 s of the run is 1.0 here) and their targets
GOALS = [(1.0, -1), (2.357, 7), (2.898, -1)]
# how long each request took to reach the scheduler, in the recording (s)
DELAYS = [0.0016, 0.0040, 0.0010]


def vision_requests():
    vision = VisionControl("vision")
    engine = Engine(vision)
    for t, target in GOALS:
        goal = LOOK_GOAL(target=target, x=0.0 if target < 0 else 0.37, y=0.0 if target < 0 else -0.27,
                         vy=0.0 if target < 0 else -0.05, t=t)
        engine.post(None, "goal", goal, t=t)
    engine.run(until=6.0)
    return [(e["t"], e["value"]) for e in engine.trace if e["action"] == "req" and e["kind"] == "output"]


def test_vision_waits_out_the_switching_time_and_a_margin_between_requests():
    requests = vision_requests()
    assert [r["control"]["id"] for _, r in requests] == ["look--1-1", "look-7-2", "look--1-3"]
    sent = [t for t, _ in requests]
    assert sent[2] - sent[1] >= REQ_SWITCHING + VisionControl.switching_margin.default - 1e-9
    assert VisionControl.switching_margin.default > max(DELAYS) - min(DELAYS)


def test_the_scheduler_takes_every_request_delivered_with_the_recordings_delays():
    requests = vision_requests()
    scheduler = load_iota(FOLDER / "resume_program.iota", N=2, T=0.05)
    engine = Engine(scheduler)
    for (t, request), delay in zip(requests, DELAYS):
        engine.post(None, "req", request, index=0, t=t + delay)
    engine.run(until=6.0)
    dropped = [e for e in engine.trace if e["kind"] == "violation"]
    assert dropped == []
    programs = [e["value"]["id"] for e in engine.trace if e["action"] == "mdl_command" and e["kind"] == "output"]
    assert programs[-1] == "look--1-3"   # the arm looks where vision asked last
    assert programs == ["look--1-1", "look-7-2", "look--1-3"]
