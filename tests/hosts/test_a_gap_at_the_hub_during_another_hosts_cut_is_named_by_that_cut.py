"""The bad day's reading (tests/bad_day_reading.py) names each gap of a merge by the fault that
caused it. A few of camera's events that reach camera's own file but not the hub's, while arm's
link is cut or slowed or its backlog drains, are named by arm's fault: every 10-minute campaign
and one run of the short one showed 1 to 22 such events at a heal or a slowdown's end. Outside
every such window, or for a host's own recording, another host's fault names nothing."""
from bad_day_reading import cause_of
from bad_day_run import Done, arm_over_three_hosts
from fault_schedule import Fault

BEGAN = 1_000_000_000_000_000_000
S = 1_000_000_000


def made(at: float, kind: str, host: str, duration: float, target: str = "") -> Done:
    return Done(Fault(at, kind, host, duration, target, "1mbit" if kind == "slow" else ""),
                BEGAN + int(at * S), BEGAN + int((at + duration) * S))


def test_camera_events_the_hub_lacks_during_a_slowdown_of_arm_are_named_by_it_and_only_then():
    _, machine = arm_over_three_hosts("10.0.0.1", 7000, "10.0.0.2", "10.0.0.3", 60)
    done = [made(18.8, "slow", "arm", 6.9), made(31.1, "kill", "camera", 0.0, "recorder")]
    at_hub = "1 event(s) of its nodes did not reach the hub's recording (the host's own recording holds them)"
    gap = {"host": "camera", "from_ns": BEGAN + int(29.0 * S), "reason": at_hub}
    assert cause_of(gap, done, machine) == "link brain-arm slowed to 1mbit (tc tbf) for 6.9 s at 18.8 s " \
                                          "(its backlog at the hub, it seems)"
    # long after the slowdown settled: nothing explains it
    assert cause_of(dict(gap, from_ns=BEGAN + int(45.0 * S)), done, machine) == ""
    # camera's own recording cut short is not arm's doing
    cut = {"host": "camera", "from_ns": BEGAN + int(29.0 * S), "reason": "its recording (x.mcap) was cut short"}
    assert cause_of(cut, done, machine) == ""
    # a fault of camera's own still names it first
    done.append(made(28.0, "partition", "camera", 2.0))
    assert cause_of(gap, done, machine) == "partition of camera for 2.0 s at 28.0 s"
