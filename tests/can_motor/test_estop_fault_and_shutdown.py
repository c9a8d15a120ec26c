"""Estop goes to every axis on the estop input and at shutdown; while estopped no setpoint goes
out; estop = false resets and re-arms. An axis that leaves closed loop on its own is a FAULT."""
from motor_bench import (CLEAR_ERRORS, ESTOP, IDLE, SET_AXIS_STATE, SET_INPUT_POS, Bench, heartbeat, setpoints)

ESTOP_REQUESTED, WATCHDOG_TIMER_EXPIRED = 0x2000000, 0x1000000


def test_estop_frames_to_every_axis_and_setpoints_dropped(bench):
    bench.arm_all(0.05)
    bench.post("estop", True, t=0.1)
    bench.post("setpoints", setpoints(3, [0.1, 0.1, 0.1]), t=0.11)
    bench.run(0.2)
    sent = [(t, ident, data) for t, ident, _, data in bench.sent(since=0.1) if ident & 0x1F != 0x03]
    assert sent == [(0.1, 1 << 5 | ESTOP, b""), (0.1, 2 << 5 | ESTOP, b""), (0.1, 5 << 5 | ESTOP, b"")]
    assert [(s["joint"], s["phase"]) for s in bench.status(event="ESTOP")] == [(0, "ESTOPPED"), (1, "ESTOPPED"),
                                                                               (2, "ESTOPPED")]


def test_reset_clears_errors_and_re_arms(bench):
    bench.arm_all(0.05)
    bench.post("estop", True, t=0.1)
    bench.hear(0.15, *(heartbeat(n, IDLE, error=ESTOP_REQUESTED) for n in (1, 2, 5)))
    bench.post("estop", False, t=0.2)
    bench.hear(0.25, *(heartbeat(n) for n in (1, 2, 5)))
    bench.post("setpoints", setpoints(3, [0.1, 0.1, 0.1]), t=0.3)
    bench.run(0.3)
    rearm = [ident for _, ident, rtr, _ in bench.sent(since=0.2, until=0.2) if not rtr]
    assert [i & 0x1F for i in rearm[:4]] == [CLEAR_ERRORS, 0x0B, 0x0F, SET_AXIS_STATE]
    assert len(rearm) == 12
    assert [s["event"] for s in bench.status(joint=0)] == [
        "ARM_SENT", "ARM_DONE", "ESTOP", "AXIS_ERROR", "RESET", "ARM_SENT", "ARM_DONE"]
    assert len([1 for _, ident, _, _ in bench.sent(since=0.3) if ident & 0x1F == SET_INPUT_POS]) == 3


def test_an_estopped_axis_that_still_shows_closed_loop_gets_estop_again(bench):
    bench.arm_all(0.05)
    bench.post("estop", True, t=0.1)
    bench.hear(0.15, heartbeat(2))  # it missed the estop
    bench.run(0.15)
    assert [(t, ident) for t, ident, rtr, _ in bench.sent(since=0.15) if not rtr] == [(0.15, 2 << 5 | ESTOP)]


def test_shutdown_hook_sends_estop_to_every_axis(bench):
    bench.arm_all(0.05)
    assert bench.final_frames() == [(1 << 5 | ESTOP, False, b""), (2 << 5 | ESTOP, False, b""),
                                    (5 << 5 | ESTOP, False, b"")]


def test_an_axis_leaving_closed_loop_is_a_fault_until_reset(bench):
    bench.arm_all(0.05)
    for k in range(1, 17):
        bench.hear(0.1 * k, heartbeat(1, IDLE, error=WATCHDOG_TIMER_EXPIRED), heartbeat(2), heartbeat(5))
    bench.post("setpoints", setpoints(3, [0.1, 0.1, 0.1]), t=0.2)
    bench.run(1.5)
    (fault,) = bench.status(event="DISARMED")
    assert (fault["t"], fault["joint"], fault["phase"], fault["axis_error"]) == (0.1, 0, "FAULT", WATCHDOG_TIMER_EXPIRED)
    assert [ident >> 5 for _, ident, _, _ in bench.sent(since=0.2) if ident & 0x1F == SET_INPUT_POS] == [2, 5]
    assert not [1 for _, ident, _, _ in bench.sent(since=0.1) if ident & 0x1F == CLEAR_ERRORS]  # no re-arm
    bench.post("estop", False, t=1.6)
    bench.run(1.6)
    assert [ident for _, ident, _, _ in bench.sent(since=1.6)][:1] == [1 << 5 | CLEAR_ERRORS]


def test_auto_rearm_re_arms_after_the_retry_delay():
    bench = Bench(auto_rearm=True, arm_retry=0.25, polls={})
    bench.arm_all(0.05)
    bench.hear(0.1, heartbeat(1, IDLE, error=WATCHDOG_TIMER_EXPIRED))
    bench.run(0.5)
    assert [(t, ident & 0x1F) for t, ident, _, _ in bench.sent(since=0.1)][:1] == [(0.1 + 0.25, CLEAR_ERRORS)]
    assert bench.status(event="DISARMED")[0]["phase"] == "UNARMED"
