"""auto_rearm is bounded and backs off: an ODrive axis that keeps dropping out of closed loop is
armed again after arm_retry, then after twice that, ...; past `rearm_limit` re-arms in a row it
stays in FAULT (REARM_LIMIT) until a reset (estop = false), which starts the count again. An axis
armed for `rearm_window` counts from none again. Without auto_rearm a drop-out is FAULT at once."""
from motor_bench import CLOSED_LOOP, CLEAR_ERRORS, IDLE, Bench, heartbeat

ONE = [{"name": "a", "node_id": 1}]


def arming_times(bench):
    return [t for t, ident, rtr, data in bench.sent() if ident == (1 << 5 | CLEAR_ERRORS)]


def drop_and_rearm(bench, t, rearm=True):
    """The axis drops out at t (IDLE); once the node re-arms it, it reports closed loop again."""
    before = len(arming_times(bench))
    bench.hear(t, heartbeat(1, state=IDLE))
    u = t
    while len(arming_times(bench)) == before and u < t + 5.0:  # until it arms again (or 5 s)
        u = round(u + 0.01, 6)
        bench.run(u)
    if rearm:
        bench.hear(u + 0.01, heartbeat(1, state=CLOSED_LOOP))
        bench.run(u + 0.02)
        return u + 0.02
    return u


def test_rearms_back_off_and_stop_at_the_limit_until_a_reset():
    bench = Bench(joints=ONE, auto_rearm=True, arm_retry=0.5, rearm_limit=2, heartbeat_period=10.0)
    bench.arm_all(0.05)
    t = drop_and_rearm(bench, 0.1)
    t = drop_and_rearm(bench, t + 0.1)
    drop_and_rearm(bench, t + 0.1, rearm=False)
    arms = arming_times(bench)
    assert arms[0] == 0.0 and len(arms) == 3
    assert round(arms[1] - 0.1, 6) == 0.5          # the first re-arm: arm_retry after the drop-out
    assert round(arms[2] - (arms[1] + 0.02 + 0.1), 6) == 1.0  # the second: twice that
    events = [s["event"] for s in bench.status(0)]
    assert events[-2:] == ["DISARMED", "REARM_LIMIT"] and bench.status(0)[-1]["phase"] == "FAULT"
    end = bench.sent()[-1][0]
    bench.post("estop", False, end + 1.0)       # a reset: arms at once, the count from none
    bench.run(end + 1.1)
    assert arming_times(bench)[-1] == end + 1.0
    assert not bench.violations()


def test_without_auto_rearm_a_drop_out_is_fault_until_a_reset():
    bench = Bench(joints=ONE, heartbeat_period=10.0)
    bench.arm_all(0.05)
    bench.hear(0.1, heartbeat(1, state=IDLE))
    bench.run(3.0)
    assert len(arming_times(bench)) == 1 and bench.status(0)[-1]["phase"] == "FAULT"


def test_an_axis_armed_for_the_window_counts_from_none_again():
    bench = Bench(joints=ONE, auto_rearm=True, arm_retry=0.5, rearm_limit=1, rearm_window=2.0, heartbeat_period=10.0)
    bench.arm_all(0.05)
    t = drop_and_rearm(bench, 0.1)     # re-arm 1 of 1
    drop_and_rearm(bench, t + 3.0)     # armed 3 s > the window: again allowed, after arm_retry
    arms = arming_times(bench)
    assert len(arms) == 3 and round(arms[2] - (t + 3.0), 6) == 0.5
    assert "REARM_LIMIT" not in [s["event"] for s in bench.status(0)]
