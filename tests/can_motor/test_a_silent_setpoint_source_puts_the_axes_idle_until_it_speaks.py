"""The link watch of the CAN motor node (`link_timeout`): once setpoints have come, none for
`link_timeout` (the network to their source is cut, or the source died) commands every armed axis
IDLE at once, stops the keep-alive that would feed the firmware's watchdog, and reports LINK_LOST
per joint; nothing re-arms while the source is silent. When setpoints come back (LINK_FOUND) the
axes the watch stopped re-arm and follow them; an axis in FAULT of its own, or estopped, stays so.
Off (0), the default, a silent source leaves the arm held by the keep-alive as before."""
import struct

from motor_bench import (CLEAR_ERRORS, CLOSED_LOOP, IDLE, SET_AXIS_STATE, SET_INPUT_POS, Bench, encoder, heartbeat,
                         setpoints)

JOINTS = [{"name": "a", "node_id": 1}, {"name": "b", "node_id": 2}]


def armed_with_setpoints(until: float = 0.1, **params) -> Bench:
    """Two axes armed at 0.015 (and beating in closed loop every 0.1 s till 0.2, then IDLE, as
    the axes do when told), setpoints every 10 ms from 0.02 to `until`, then silence."""
    bench = Bench(JOINTS, polls={}, **params)
    bench.hear(0.005, encoder(1, 0.0), encoder(2, 0.0))
    bench.hear(0.015, heartbeat(1), heartbeat(2))
    if params.get("link_timeout"):
        bench.hear(0.115, heartbeat(1), heartbeat(2))
        for k in range(2, 10):
            bench.hear(k / 10 + 0.015, heartbeat(1, state=IDLE), heartbeat(2, state=IDLE))
    else:
        for k in range(1, 10):
            bench.hear(k / 10 + 0.015, heartbeat(1), heartbeat(2))
    for k in range(2, round(until * 100) + 1):
        bench.post("setpoints", setpoints(2, [0.01 * k, -0.01 * k]), t=k / 100)
    return bench


def frames(bench, cmd, since=0.0):
    return [(round(t, 9), ident >> 5, data) for t, ident, rtr, data in bench.sent(since=since)
            if not rtr and ident & 0x1F == cmd]


def state(node, axis_state):
    """Set_Axis_State's data: the state, zero-padded to the DLC of 8 the DBC gives."""
    return (node, struct.pack("<Ixxxx", axis_state))


def test_silence_past_link_timeout_commands_idle_and_stops_the_keepalive():
    bench = armed_with_setpoints(link_timeout=0.05, keepalive=0.03, auto_rearm=True)
    bench.run(1.0)
    # the last setpoint at 0.1 (taken before that instant's tick); 0.05 s of silence at 0.15
    assert frames(bench, SET_AXIS_STATE, since=0.02) == [(0.15, *state(1, IDLE)), (0.15, *state(2, IDLE))]
    lost = bench.status(event="LINK_LOST")
    assert [(s["t"], s["joint"], s["phase"]) for s in lost] == [(0.15, 0, "FAULT"), (0.15, 1, "FAULT")]
    # the keep-alive fed the watchdog at 0.12 (3 ticks after the last setpoint); from the cut, nothing
    assert [t for t, *_ in frames(bench, SET_INPUT_POS, since=0.101)] == [0.12, 0.12]
    assert frames(bench, CLEAR_ERRORS, since=0.02) == []  # and no arming while the source is silent
    assert bench.violations() == []


def test_setpoints_again_rearm_the_axes_and_are_followed():
    bench = armed_with_setpoints(link_timeout=0.05)
    bench.hear(0.2, heartbeat(1, state=IDLE), heartbeat(2, state=IDLE))  # the axes obeyed
    bench.post("setpoints", setpoints(2, [0.5, -0.5]), t=0.5)  # the network healed
    bench.hear(0.52, heartbeat(1), heartbeat(2))
    bench.post("setpoints", setpoints(2, [0.6, -0.6]), t=0.53)
    bench.run(0.55)
    assert [s["t"] for s in bench.status(event="LINK_FOUND")] == [0.5, 0.5]
    arming = frames(bench, SET_AXIS_STATE, since=0.3)
    assert arming == [(0.5, *state(1, CLOSED_LOOP)), (0.5, *state(2, CLOSED_LOOP))]
    assert [s["t"] for s in bench.status(event="ARM_DONE")] == [0.015, 0.015, 0.52, 0.52]
    followed = frames(bench, SET_INPUT_POS, since=0.525)
    assert [(t, node, round(struct.unpack("<f", data[:4])[0], 6)) for t, node, data in followed] == \
        [(0.53, 1, round(0.6 / 6.283185307179586, 6)), (0.53, 2, round(-0.6 / 6.283185307179586, 6))]


def test_an_axis_faulted_before_the_cut_or_estopped_during_it_is_not_rearmed():
    bench = armed_with_setpoints(link_timeout=0.05)
    bench.hear(0.06, heartbeat(2, state=IDLE))  # axis 2 drops out on its own: FAULT (no auto_rearm)
    bench.post("setpoints", setpoints(2), t=0.5)
    bench.run(0.8)
    assert [(s["t"], s["joint"]) for s in bench.status(event="DISARMED")] == [(0.06, 1)]
    assert [t for t, node, _ in frames(bench, CLEAR_ERRORS, since=0.3)] == [0.5]  # axis 1's arming only
    assert [s["phase"] for s in bench.status(joint=1, event="LINK_FOUND")] == ["FAULT"]
    estopped = armed_with_setpoints(link_timeout=0.05)
    estopped.post("estop", True, t=0.3)
    estopped.post("setpoints", setpoints(2), t=0.5)
    estopped.run(0.8)
    assert frames(estopped, CLEAR_ERRORS, since=0.3) == []
    assert {s["phase"] for s in estopped.status(event="LINK_FOUND")} == {"ESTOPPED"}


def test_off_by_default_and_never_before_the_first_setpoint():
    bench = armed_with_setpoints(keepalive=0.05)
    bench.run(1.0)
    assert bench.status(event="LINK_LOST") == [] and frames(bench, SET_AXIS_STATE, since=0.02) == []
    assert frames(bench, SET_INPUT_POS, since=0.9)  # the keep-alive holds the arm, as before
    quiet = Bench(JOINTS, polls={}, link_timeout=0.05)  # armed, but no source has spoken yet
    quiet.hear(0.005, encoder(1, 0.0), encoder(2, 0.0))
    quiet.hear(0.015, heartbeat(1), heartbeat(2))
    quiet.run(1.0)
    assert quiet.status(event="LINK_LOST") == []
