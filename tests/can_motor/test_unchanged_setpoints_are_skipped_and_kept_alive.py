"""`skip_unchanged = true`: a setpoint whose frame is the one the axis was sent last does not go
out again; the keep-alive repeats that very frame (feed-forward and all) often enough for the
firmware's watchdog, and the first command after (re-)arming always goes out. With the simulated
ODrives (watchdog 80 ms) an arm holding still under a 50 Hz source stays armed on a fraction of
the frames."""
import struct

import pytest

from iotad.kernel.model import SpecError

from motor_bench import SET_INPUT_POS, SET_INPUT_VEL, TAU, Bench, heartbeat, setpoints

JOINTS = [{"name": "a", "node_id": 1}, {"name": "w", "node_id": 2, "mode": "velocity"}]


def commands(bench, since=0.001):
    """The setpoint frames sent from `since` on (by default after the arming frames at 0, which
    end with the velocity joint's hold command)."""
    return [(round(t, 9), ident, data) for t, ident, rtr, data in bench.sent(since=since)
            if not rtr and ident & 0x1F in (SET_INPUT_POS, SET_INPUT_VEL)]


def test_only_changes_go_out_and_the_keepalive_repeats_the_last_frame():
    bench = Bench(JOINTS, keepalive=0.05, polls={}, skip_unchanged=True, state_period=0.01)
    bench.arm_all(0.005)
    same = setpoints(2, [0.5, 0.0], velocity_ff=[0.25, 1.0], torque_ff=[0.0, 0.0])
    for k in range(8):  # 0.02 .. 0.09, every 10 ms: unchanged
        bench.post("setpoints", same, t=0.02 + 0.01 * k)
    bench.post("setpoints", setpoints(2, [0.6, 0.0], velocity_ff=[0.25, 1.0]), t=0.1)
    bench.run(0.125)
    a = struct.pack("<fhh", 0.5 / TAU, round(0.25 / TAU * 1000), 0)
    w = struct.pack("<ff", 1.0 / TAU, 0.0)
    assert commands(bench) == [
        (0.02, 1 << 5 | SET_INPUT_POS, a), (0.02, 2 << 5 | SET_INPUT_VEL, w),   # the first: sent
        # 0.03 .. 0.05 unchanged: nothing. The keep-alive counts whole ticks from the tick before
        # the send (0.01), so the same frames come again at 0.06, feed-forward kept (the source
        # is not silent: its setpoint is unchanged)
        (0.06, 1 << 5 | SET_INPUT_POS, a), (0.06, 2 << 5 | SET_INPUT_VEL, w),
        # a changed joint goes out at once; the unchanged one waits for its keep-alive
        (0.1, 1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 0.6 / TAU, round(0.25 / TAU * 1000), 0)),
        (0.11, 2 << 5 | SET_INPUT_VEL, w),
    ]


def test_every_setpoint_goes_out_by_default():
    bench = Bench(JOINTS, keepalive=0.05, polls={}, state_period=0.01)
    bench.arm_all(0.005)
    for k in range(4):
        bench.post("setpoints", setpoints(2, [0.5, 0.0], velocity_ff=[0.0, 1.0]), t=0.02 + 0.01 * k)
    bench.run(0.055)
    assert [t for t, *_ in commands(bench)] == [0.02, 0.02, 0.03, 0.03, 0.04, 0.04, 0.05, 0.05]


def test_the_first_command_after_re_arming_goes_out_even_if_unchanged():
    bench = Bench(JOINTS[:1], keepalive=0.05, polls={}, skip_unchanged=True, state_period=0.01, auto_rearm=True)
    bench.arm_all(0.005)
    bench.post("setpoints", setpoints(1, [0.5]), t=0.02)
    for k in range(1, 6):  # the axis dropped to IDLE: UNARMED, re-armed arm_retry (0.5 s) later
        bench.hear(0.03 + 0.1 * (k - 1), heartbeat(1, state=1))
    bench.hear(0.6, heartbeat(1))                  # closed loop again: ARMED
    bench.post("setpoints", setpoints(1, [0.5]), t=0.61)
    bench.run(0.615)
    sent = [t for t, ident, _ in commands(bench) if ident == 1 << 5 | SET_INPUT_POS]
    assert [e["value"]["event"] for e in bench.events("joint_status") if e["value"]["event"] in
            ("DISARMED", "ARM_SENT", "ARM_DONE")][-3:] == ["DISARMED", "ARM_SENT", "ARM_DONE"]
    assert sent[0] == 0.02 and sent[-1] == 0.61  # the same setpoint: out again, the axis is new to it


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_skip_unchanged_is_a_bool_and_needs_a_keepalive(bad):
    with pytest.raises(SpecError, match="parameter skip_unchanged: expected true or false"):
        Bench(JOINTS, keepalive=0.05, skip_unchanged=bad)
    with pytest.raises(ValueError, match="skip_unchanged needs a keepalive"):
        Bench(JOINTS, keepalive=0.0, skip_unchanged=True)


def test_a_lost_axis_gets_every_setpoint_even_unchanged():
    """LOST (no heartbeat for 3 periods) yet maybe running: the keep-alive skips it, so skipping
    its unchanged setpoints too would starve its watchdog."""
    bench = Bench(JOINTS[:1], keepalive=0.05, polls={}, skip_unchanged=True, state_period=0.01)
    bench.arm_all(0.005)  # its only heartbeat: LOST from 0.305
    for k in range(40):
        bench.post("setpoints", setpoints(1, [0.5]), t=0.02 + 0.01 * k)
    bench.run(0.415)
    assert [s["t"] for s in bench.status(0, "LOST")] == [pytest.approx(0.305)]
    after = [t for t, *_ in commands(bench, since=0.31)]
    assert after == pytest.approx([0.31 + 0.01 * k for k in range(11)])  # every one


def test_a_silent_source_gets_its_last_command_without_feed_forward():
    """Unchanged setpoints still coming: the keep-alive repeats the frame, feed-forward and all;
    the source fallen silent: the command alone, as without skip_unchanged."""
    bench = Bench(JOINTS[:1], keepalive=0.05, polls={}, skip_unchanged=True, state_period=0.01)
    bench.arm_all(0.005)
    for k in range(3):  # 0.02 .. 0.04, then silence
        bench.post("setpoints", setpoints(1, [0.5], velocity_ff=[0.25]), t=0.02 + 0.01 * k)
    bench.run(0.125)
    sent = commands(bench)
    assert sent[0] == (0.02, 1 << 5 | SET_INPUT_POS, struct.pack("<fhh", 0.5 / TAU, round(0.25 / TAU * 1000), 0))
    # 0.06: the last setpoints came 20 ms ago, within a keep-alive period: unchanged, repeated as
    # it is; 0.11 (a keep-alive later): none for 70 ms, the source is silent: the position alone
    assert [(t, data) for t, _, data in sent[1:]] == [(0.06, sent[0][2]), (0.11, struct.pack("<fhh", 0.5 / TAU, 0, 0))]
