"""A controller whose heartbeat is missing for 3 periods is reported LOST, exactly then; a heartbeat
again reports it FOUND; joint states keep flowing (the status says which joint is stale)."""
from motor_bench import Bench, encoder, f32, heartbeat

JOINTS = [{"name": "a", "node_id": 1}, {"name": "b", "node_id": 2}]


def beat(bench, node, times):
    for t in times:
        bench.hear(t, heartbeat(node))


def test_lost_exactly_three_heartbeat_periods_after_the_last_one():
    bench = Bench(JOINTS, polls={})
    beat(bench, 1, [0.05 + 0.1 * k for k in range(20)])    # a: alive throughout
    beat(bench, 2, [0.05 + 0.1 * k for k in range(6)])     # b: dies after the beat at 0.55
    bench.run(2.0)
    lost = bench.status(event="LOST")
    assert [(s["t"], s["joint"], s["lost"]) for s in lost] == [(0.85, 1, True)]  # 0.55 + 3 x 0.1
    assert not bench.status(joint=0, event="LOST")
    # no Get_Error polls or other requests go to a lost axis
    assert all(ident >> 5 != 2 for t, ident, _, _ in bench.sent(since=0.86))


def test_a_late_heartbeat_is_not_lost_and_a_returning_one_is_found():
    bench = Bench(JOINTS, polls={})
    beat(bench, 1, [0.05 + 0.1 * k for k in range(20)])
    beat(bench, 2, [0.05, 0.34])           # 0.29 s gap: under three periods
    beat(bench, 2, [1.0, 1.1])             # lost at 0.64, back at 1.0
    bench.run(1.15)
    assert [(s["t"], s["event"]) for s in bench.status(joint=1) if s["event"] in ("LOST", "FOUND")] == [
        (0.64, "LOST"), (1.0, "FOUND")]  # 0.34 + 3 x 0.1
    assert bench.status(joint=1)[-1]["lost"] is False


def test_an_axis_never_heard_is_lost_at_three_periods_and_states_carry_on():
    bench = Bench(JOINTS, heartbeat_period=0.05, polls={})
    beat(bench, 1, [0.02 + 0.05 * k for k in range(10)])
    bench.hear(0.01, encoder(1, 0.1), encoder(2, 0.2))
    bench.run(0.305)
    assert [(s["t"], s["joint"]) for s in bench.status(event="LOST")] == [(0.15, 1)]  # 3 x 0.05
    states = bench.events("joint_states")
    assert len(states) == 30  # every 10 ms, lost joint or not: its last position stays
    assert states[-1]["value"]["position"][1] == bench.motor.joint_map[1].position(f32(0.2))


def test_lost_after_and_heartbeat_period_set_the_time():
    bench = Bench(JOINTS, heartbeat_period=0.2, lost_after=5, polls={})
    beat(bench, 1, [0.1 * k for k in range(30)])
    beat(bench, 2, [0.1])
    bench.run(2.0)
    assert [s["t"] for s in bench.status(event="LOST")] == [1.1]  # 0.1 + 5 x 0.2
