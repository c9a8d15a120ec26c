"""A real-time receiver whose socket opened just before its engine started hears the last of the
twins (the same frame sent again and again, as an ODrive's heartbeat is) sent before the start.
The delivery check keeps as many of those early twins as the receiver heard beyond the ones sent
after its start; the sender's twins sent after the receiver's last reception (it had stopped:
the sender outlived it) reached nothing and must not count among the ones it heard, or the twin
it did hear first is dropped and its first reception judged 'altered' (seen once in the suite:
"pinger sent frame 0x010 [00], echo received 0x010 [00]")."""
from types import SimpleNamespace

from iotad.recording.delivery_accounts import Life
from iotad.recording.delivery_can import check_bus

HEARTBEAT = {"id": 0x010, "extended": False, "rtr": False, "dlc": 1, "data": [0]}
PERIOD = 0.01


def _event(t: float, kind: str, action: str) -> SimpleNamespace:
    return SimpleNamespace(t=t, kind=kind, action=action, value=HEARTBEAT, raw={})


def _accounts(echo_start: float, echo_last: float, pinger_end: float) -> SimpleNamespace:
    sends = [round(k * PERIOD, 6) for k in range(int(round(pinger_end / PERIOD)) + 1)]
    # the echo's socket opened 6 ms before its engine started: it heard the one twin sent then
    heard = [t for t in sends if echo_start - 0.006 <= t <= echo_last]
    events = {"pinger": [_event(t, "output", "can_tx") for t in sends],
              "echo": [_event(t + 0.0004, "input", "can_rx") for t in heard]}
    life = {"pinger": Life([0.0], [pinger_end], None), "echo": Life([echo_start], [echo_last + 0.0004], None)}
    return SimpleNamespace(events=events, life=life, tolerance=1e-9, unit=1.0, virtual=False,
                           can_window=lambda: 0.1, system=SimpleNamespace(external=set()))


def _echo_link(acc):
    rows = check_bus(acc, "can0", ["pinger", "echo"], {
        s: [(e.t, (0x010, False, False, 1, (0,))) for e in acc.events[s] if e.action == "can_tx"]
        for s in ("pinger", "echo")})
    link = next(link for link in rows.links if link.label == "can can0: pinger -> echo")
    return link, rows


def test_the_twin_heard_just_before_the_start_is_delivered_when_the_sender_outlives_the_receiver():
    # echo started at 0.055 and stopped hearing at 0.15; the pinger went on sending until 0.20
    link, rows = _echo_link(_accounts(echo_start=0.055, echo_last=0.15, pinger_end=0.20))
    problems = [f.message for f in rows.findings if f.link == link.label]
    assert link.altered == 0 and link.lost == 0, problems
    assert link.delivered == 11  # the twin sent at 0.05 and the ten sent from 0.06 to 0.15
    unjudged = [f.message for f in rows.findings + rows.notes if f.code == "not judged"]
    assert any("before echo's engine started" in m for m in unjudged)  # the five before it, not heard


def test_the_twin_heard_just_before_the_start_is_delivered_when_both_stop_together():
    link, rows = _echo_link(_accounts(echo_start=0.055, echo_last=0.20, pinger_end=0.20))
    assert link.altered == 0 and link.lost == 0
    assert link.delivered == 16
