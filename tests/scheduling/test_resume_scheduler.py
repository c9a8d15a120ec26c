"""nodes/scheduler/resume.iota: a preempted request is suspended and resumed with what is left of
its epoch; priorities change at run time; a suspended request times out. Exact traces in virtual
time under the eager policy, random-policy runs checked for conformance, and Figure 2's
behaviour kept wherever nothing is preempted."""
import json

import pytest

from iotad.cli import main
from iotad.esprit import load_iota
from iotad.kernel.input_script import parse_script

from scheduling_helpers import (EXAMPLES, FIGURE2, RESUME, acks, assert_conforms, mode, priority, req, run, story,
                      violations)


def scheduler(**params):
    return load_iota(str(RESUME), **params)


def test_a_preempted_request_is_suspended_and_resumes_with_its_remaining_epoch():
    engine = run(scheduler(), [req(0.0, 0, 1, epoch=5.0, w=0.1), req(1.0, 1, 5, epoch=2.0, w=0.9)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),
        (1.0, "schedule", 1, None), (1.0, "mdl_command", None, mode(0.9)),        # 0 suspended, 4 left
        (3.0, "commit", 1, None), (3.0, "schedule", 0, None),                     # motors free: 0 resumes
        (3.0, "mdl_command", None, mode(0.1)), (3.0, "ack", 1, "COMMIT"),         # its mode signalled again
        (7.0, "commit", 0, None), (7.0, "ack", 0, "COMMIT")]                       # 3 + (5 - 1)
    state = engine.iota("scheduler_resume")
    assert state.current_master is None and [r.status for r in state.request] == ["NULL", "NULL"]


def test_nested_resume_with_three_requesters():
    engine = run(scheduler(N=3), [req(0.0, 0, 1, epoch=6.0, w=0.0), req(1.0, 1, 3, epoch=4.0, w=0.1),
                                  req(2.0, 2, 5, epoch=2.0, w=0.2)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.0)),
        (1.0, "schedule", 1, None), (1.0, "mdl_command", None, mode(0.1)),        # 0 suspended, 5 left
        (2.0, "schedule", 2, None), (2.0, "mdl_command", None, mode(0.2)),        # 1 suspended, 3 left
        (4.0, "commit", 2, None), (4.0, "schedule", 1, None),                     # the higher of 0 and 1
        (4.0, "mdl_command", None, mode(0.1)), (4.0, "ack", 2, "COMMIT"),
        (7.0, "commit", 1, None), (7.0, "schedule", 0, None),
        (7.0, "mdl_command", None, mode(0.0)), (7.0, "ack", 1, "COMMIT"),
        (12.0, "commit", 0, None), (12.0, "ack", 0, "COMMIT")]


def test_a_suspended_request_not_resumed_within_its_timeout_is_aborted():
    engine = run(scheduler(), [req(0.0, 0, 1, epoch=5.0, timeout=2.0, w=0.1), req(1.0, 1, 5, epoch=4.0, w=0.9)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),
        (1.0, "schedule", 1, None), (1.0, "mdl_command", None, mode(0.9)),
        (3.0, "expire", 0, None), (3.0, "ack", 0, "ABORT"),                      # timeout counted from 1.0
        (5.0, "commit", 1, None), (5.0, "ack", 1, "COMMIT")]


def test_the_suspension_timeout_restarts_at_each_suspension():
    # 0 is suspended at 1 (timeout 2.5), resumed at 3, suspended again at 4: it expires at 6.5, not 3.5
    engine = run(scheduler(N=3), [req(0.0, 0, 1, epoch=5.0, timeout=2.5), req(1.0, 1, 5, epoch=2.0),
                                  req(4.0, 2, 5, epoch=4.0)])
    assert acks(engine) == [(3.0, 1, "COMMIT"), (6.5, 0, "ABORT"), (8.0, 2, "COMMIT")]


def test_a_waiting_request_raised_above_the_master_preempts_it():
    engine = run(scheduler(), [req(0.0, 0, 2, epoch=4.0, w=0.1), req(0.5, 1, 1, epoch=2.0, w=0.9),
                               priority(1.5, 1, 5)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),       # 1 waits: priority 1 < 2
        (1.5, "schedule", 1, None), (1.5, "mdl_command", None, mode(0.9)),       # raised to 5: 0 suspended
        (3.5, "commit", 1, None), (3.5, "schedule", 0, None),
        (3.5, "mdl_command", None, mode(0.1)), (3.5, "ack", 1, "COMMIT"),
        (6.0, "commit", 0, None), (6.0, "ack", 0, "COMMIT")]                     # 3.5 + (4 - 1.5)


def test_a_master_lowered_below_a_waiting_request_is_suspended():
    engine = run(scheduler(), [req(0.0, 0, 3, epoch=4.0, w=0.1), req(1.0, 1, 2, epoch=1.0, w=0.9),
                               priority(2.0, 0, 1)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),
        (2.0, "schedule", 1, None), (2.0, "mdl_command", None, mode(0.9)),       # lowered to 1 < 2
        (3.0, "commit", 1, None), (3.0, "schedule", 0, None),
        (3.0, "mdl_command", None, mode(0.1)), (3.0, "ack", 1, "COMMIT"),
        (5.0, "commit", 0, None), (5.0, "ack", 0, "COMMIT")]                     # 3 + (4 - 2)
    assert engine.iota("scheduler_resume").request[0].command.priority == 1


def test_priority_changes_that_keep_the_order_change_nothing_but_the_priorities():
    inputs = [req(0.0, 0, 3, epoch=4.0), req(1.0, 1, 2, epoch=1.0)]
    plain = run(scheduler(), inputs)
    raised = run(scheduler(), inputs + [priority(1.5, 0, 4), priority(2.0, 1, 3)])
    assert story(raised) == story(plain)
    assert [r.command.priority for r in raised.iota("scheduler_resume").request] == [4, 3]


def test_the_highest_waiting_request_takes_the_free_motors_and_no_other_is_scheduled():
    # 0 holds the motors; 1 (priority 2) and 2 (priority 4) wait; when 0 commits, 2 goes first
    engine = run(scheduler(N=3), [req(0.0, 0, 9, epoch=2.0), req(0.5, 1, 2, epoch=1.0), req(0.5, 2, 4, epoch=1.0)])
    assert [(t, i) for t, a, i, _ in story(engine) if a == "schedule"] == [(0.0, 0), (2.0, 2), (3.0, 1)]
    assert acks(engine) == [(2.0, 0, "COMMIT"), (3.0, 2, "COMMIT"), (4.0, 1, "COMMIT")]


def test_a_new_request_from_the_master_frees_the_motors_for_it():
    engine = run(scheduler(), [req(0.0, 0, 1, epoch=5.0, w=0.1), req(2.0, 0, 1, epoch=1.0, w=0.3)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),
        (2.0, "schedule", 0, None), (2.0, "mdl_command", None, mode(0.3)),
        (3.0, "commit", 0, None), (3.0, "ack", 0, "COMMIT")]


def test_a_request_preempted_before_it_signalled_waits_again_and_is_rejected_as_in_figure2():
    # 1 is scheduled at 0.5 but mdl_command waits out its switching time until 1.0; 2 takes over at
    # 0.7: 1 was never signalled, so it is PENDING again and its timeout still counts from 0.5.
    # 2 signals from 1.0 (the switching time), so it commits at 4.0; 0 then resumes with 4.5 left.
    engine = run(scheduler(N=3), [req(0.0, 0, 1, epoch=5.0, timeout=10.0), req(0.5, 1, 3, timeout=1.5),
                                  req(0.7, 2, 5, epoch=3.0)])
    assert [(t, i) for t, a, i, _ in story(engine) if a == "schedule"] == [(0.0, 0), (0.5, 1), (0.7, 2),
                                                                           (4.0, 0)]
    assert [t for t, a, _, _ in story(engine) if a == "mdl_command"] == [0.0, 1.0, 4.0]
    assert acks(engine) == [(2.0, 1, "REJECT"), (4.0, 2, "COMMIT"), (8.5, 0, "COMMIT")]



def test_a_master_rejected_before_its_mode_went_out_lets_the_suspended_one_resume():
    # 1 takes the motors at 0.4 (0 suspended, 3.6 left); its mode waits for mdl_command's
    # switching time (1.0) and it times out at 0.7: 0 resumes then, its mode goes out at 1.0,
    # and the motors are free again for the priority-4 request at 8
    engine = run(scheduler(), [req(0.0, 0, 1, epoch=4.0, w=0.1), req(0.4, 1, 5, timeout=0.3),
                               req(8.0, 0, 4, epoch=1.0, timeout=1.0)])
    assert [(t, i) for t, a, i, _ in story(engine) if a == "schedule"] == [(0.0, 0), (0.4, 1), (0.7, 0), (8.0, 0)]
    assert [t for t, a, _, _ in story(engine) if a == "mdl_command"] == [0.0, 1.0, 8.0]
    assert acks(engine) == [(0.7, 1, "REJECT"), (4.6, 0, "COMMIT"), (9.0, 0, "COMMIT")]
    assert not violations(engine)


def test_a_master_lowered_below_zero_lets_no_request_of_priority_zero_or_less_take_the_motors():
    engine = run(scheduler(), [req(0.0, 0, 3, epoch=4.0), priority(1.0, 0, -5), req(2.0, 1, -2, timeout=1.0)])
    assert [(t, i) for t, a, i, _ in story(engine) if a == "schedule"] == [(0.0, 0)]
    assert acks(engine) == [(3.0, 1, "REJECT"), (4.0, 0, "COMMIT")]


def test_a_request_that_replaces_a_waiting_one_is_rejected_after_its_own_timeout():
    # 0 waits behind 1 with a timeout of 2; at 1.5 a new request on index 0, timeout 8, replaces
    # it: its rejection counts from 1.5 (docs/schedulers.md rule 5), not from the old request
    inputs = [req(0.0, 1, 5, epoch=10.0, timeout=20.0), req(0.0, 0, 1, timeout=2.0), req(1.5, 0, 1, timeout=8.0)]
    engine = run(scheduler(), inputs)
    assert (1.5, "renew", 0, None) in story(engine)
    assert acks(engine) == [(9.5, 0, "REJECT"), (10.0, 1, "COMMIT")]
    assert not violations(engine)
    # Figure 2 keeps the old request's window open: the new one is rejected 0.5 after it
    assert acks(run(load_iota(str(FIGURE2)), inputs))[0] == (2.0, 0, "REJECT")


def test_the_motors_go_to_the_highest_waiting_request_the_instant_they_are_free():
    # 0 resumes at 1.2 but is suspended again at 1.5, before its mode went out (mdl_command waits
    # out its switching time); when 2 commits at 2.1, 0 is scheduled at that instant although it
    # was last scheduled only 0.9 before (schedule's switching time is 0, not Figure 2's 1)
    engine = run(scheduler(N=3), [req(0.0, 0, 1, epoch=5.0, w=0.0), req(0.5, 1, 5, epoch=0.2, w=0.1),
                                  req(1.5, 2, 7, epoch=0.1, w=0.2)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.0)),
        (0.5, "schedule", 1, None), (1.0, "mdl_command", None, mode(0.1)),       # 0 suspended, 4.5 left
        (1.2, "commit", 1, None), (1.2, "schedule", 0, None), (1.2, "ack", 1, "COMMIT"),
        (1.5, "schedule", 2, None),                                              # 0 suspended again
        (2.0, "mdl_command", None, mode(0.2)),
        (2.1, "commit", 2, None), (2.1, "schedule", 0, None), (2.1, "ack", 2, "COMMIT"),
        (3.0, "mdl_command", None, mode(0.0)),                                   # mdl_command's switching time
        (7.5, "commit", 0, None), (7.5, "ack", 0, "COMMIT")]                     # 3 + 4.5
    assert not violations(engine)


def test_back_to_back_requests_on_one_index_commit_after_their_epochs():
    # Figure 2 commits the second request at 1.9 (commit's switching time 1: an unreachable window)
    inputs = [req(0.0, 0, 1, epoch=0.9), req(1.0, 0, 1, epoch=0.1)]
    assert [t for t, a, _, _ in story(run(scheduler(), inputs)) if a == "commit"] == [0.9, 1.1]
    assert acks(run(scheduler(), inputs)) == [(0.9, 0, "COMMIT"), (1.9, 0, "COMMIT")]  # ack's switching time
    assert not violations(run(scheduler(), inputs))
    figure2 = run(load_iota(str(FIGURE2)), inputs)
    assert [t for t, a, _, _ in story(figure2) if a == "commit"] == [0.9, 1.9]
    assert [v["value"]["violation"] for v in violations(figure2)] == ["unreachable_window"]

FIGURE2_SCENARIOS = {  # the scenarios of tests/esprit/test_figure2_scheduler_in_esprit.py that preempt nothing
    "commit_after_epoch": [req(0.0, 0, 1, epoch=2.0, timeout=5.0)],
    "timeout_reject": [req(0.0, 0, 5, epoch=5.0, timeout=5.0), req(0.5, 1, 1, timeout=1.0)],
    "lower_waits_then_runs": [req(0.0, 0, 5, epoch=2.0, timeout=5.0), req(0.5, 1, 1, epoch=1.0, timeout=10.0)],
    "input_sooner_than_switching": [req(0.0, 0, 1, timeout=5.0), req(0.5, 0, 1, timeout=5.0)],
}


@pytest.mark.parametrize("name", sorted(FIGURE2_SCENARIOS))
def test_without_preemption_it_behaves_as_figure2(name):
    inputs = FIGURE2_SCENARIOS[name]
    figure2 = run(load_iota(str(FIGURE2)), inputs).trace
    resume = run(scheduler(), inputs).trace
    assert [dict(e, iota="scheduler") for e in resume] == figure2


def test_preemption_is_where_it_differs_from_figure2():
    inputs = [req(0.0, 0, 1, epoch=5.0), req(1.0, 1, 5, epoch=1.0)]
    assert acks(run(load_iota(str(FIGURE2)), inputs)) == [(1.0, 0, "ABORT"), (2.0, 1, "COMMIT")]
    assert acks(run(scheduler(), inputs)) == [(2.0, 1, "COMMIT"), (6.0, 0, "COMMIT")]


EXAMPLE = [json.loads(line) for line in (EXAMPLES / "resume-inputs.jsonl").read_text().splitlines()]


def test_the_example_script_with_iotad_spec_run(capsys):
    assert main(["spec", "run", str(RESUME), "--param", "T=0.5", "--inputs", str(EXAMPLES / "resume-inputs.jsonl"),
                 "--until", "20"]) == 0
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert not [e for e in trace if e["kind"] == "violation"]
    assert [(e["t"], e["index"], e["value"]) for e in trace if e["action"] == "ack"] == [
        (3.0, 1, "COMMIT"), (7.0, 0, "COMMIT"), (8.0, 1, "COMMIT"), (11.0, 0, "ABORT"), (14.0, 1, "COMMIT")]
    assert [e["t"] for e in trace if e["action"] == "mdl_command"] == [0.0, 1.0, 3.0, 4.0, 5.0, 7.0, 9.0, 10.0]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_policy_runs_conform_to_the_spec(seed, tmp_path, capsys):
    engine = assert_conforms(lambda: scheduler(T=0.5), parse_script([json.dumps(e) for e in EXAMPLE]), 25.0,
                             seed, tmp_path)
    assert acks(engine) and "every node conforms" in capsys.readouterr().out
    # the policy moved firings inside their windows: not the eager trace
    assert acks(engine) != acks(run(scheduler(T=0.5), parse_script([json.dumps(e) for e in EXAMPLE]), 25.0))


def test_the_checker_catches_a_resume_that_commits_too_early(tmp_path):
    from iotad.recording.conformance import check_trace
    engine = run(scheduler(), [req(0.0, 0, 1, epoch=5.0), req(1.0, 1, 5, epoch=2.0)])
    tampered = [dict(e, t=6.5) if e["action"] in ("commit", "ack") and e["index"] == 0 else e for e in engine.trace]
    report = check_trace(scheduler(), tampered, until=30.0)
    assert not report.ok
    assert report.findings[0].code == "early" and "commit[0]" in report.findings[0].message


def test_bad_priorities_and_requests_are_violations_not_crashes():
    engine = run(scheduler(), [priority(0.0, 1, 3), {"t": 0.5, "action": "priority", "index": 0, "value": "high"},
                               req(1.0, 0, 1, epoch=1.0)])
    assert [v["value"]["violation"] for v in violations(engine)] == ["bad_value"]
    assert acks(engine) == [(2.0, 0, "COMMIT")]  # a priority for no request changed nothing
