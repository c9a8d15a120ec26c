"""The Figure 2 requester never waits for ever: the scheduler answers a request within its timeout
and epoch (and its ack window), so a requester that has heard nothing `patience` seconds past
them takes the request as aborted and goes on with its next one after its pause. That covers an
answer lost between hosts, and one refused because, held up by a partition, the answer before it
arrived late and this one came sooner after it than the ack's switching time (in virtual time)."""
from iotad.kernel.engine import Engine
from requesters import Requester

PARAMS = dict(priority=1, epoch=1.0, timeout=2.0, start=0.5, pause=1.0, count=2, patience=2.0)


def fired(engine, action, kind="output"):
    return [(round(e["t"], 9), e["value"]) for e in engine.trace if e["action"] == action and e["kind"] == kind]


def test_no_answer_is_an_abort_after_timeout_epoch_and_patience():
    requester = Requester("vision", **PARAMS)
    engine = Engine(requester)
    engine.run(until=12.0)
    asked = [t for t, _ in fired(engine, "req")]
    gave_up = [t for t, _ in fired(engine, "no_answer", "internal")]
    assert asked == [0.5, 0.5 + 5.0 + 1.0]         # the second after giving up the first, and its pause
    assert gave_up == [0.5 + 5.0, 6.5 + 5.0]       # timeout 2 + epoch 1 + patience 2 after each
    assert requester.answers == ["ABORT", "ABORT"] and not requester.waiting


def test_an_answer_refused_by_its_switching_time_is_given_up_on_not_waited_for():
    requester = Requester("vision", **dict(PARAMS, pause=0.5))
    engine = Engine(requester)
    engine.post(None, "ack", "REJECT", t=4.0)       # the first answer, late (held up by a partition)
    engine.post(None, "ack", "ABORT", t=4.8)        # the second request's answer, 0.8 s after it
    engine.run(until=12.0)
    assert [t for t, _ in fired(engine, "req")] == [0.5, 4.5]
    assert [e["value"]["violation"] for e in engine.trace if e["kind"] == "violation"] == ["switching_time"]
    assert [t for t, _ in fired(engine, "no_answer", "internal")] == [9.5]  # 4.5 + 2 + 1 + 2
    assert requester.answers == ["REJECT", "ABORT"] and not requester.waiting


def test_an_answer_in_time_is_taken_and_nothing_is_given_up():
    requester = Requester("vision", **PARAMS)
    engine = Engine(requester)
    engine.post(None, "ack", "COMMIT", t=2.0)
    engine.post(None, "ack", "COMMIT", t=4.5)
    engine.run(until=12.0)
    assert fired(engine, "no_answer", "internal") == [] and requester.answers == ["COMMIT", "COMMIT"]
