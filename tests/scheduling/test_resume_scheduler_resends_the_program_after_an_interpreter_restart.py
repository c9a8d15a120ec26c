"""nodes/scheduler/resume.iota and the conveyor's copy take restart notices (docs/failures.md):
when the node that reads mdl_command (the MDL interpreter) restarts, the program it ran for the
master is gone with it, so the master's mode is signalled again, and it still commits when its
epoch is over. A notice while nobody signals, or about another channel's peer, changes nothing."""
import pytest

from iotad.esprit import load_iota

from scheduling_helpers import EXAMPLES, RESUME, acks, assert_conforms, mode, req, run, story, violations


def restart(t, peer="mdl_command"):
    return {"t": t, "action": "peer_restart", "value": peer}


def test_an_interpreter_restart_resends_the_masters_mode_and_the_epoch_still_ends_on_time():
    engine = run(load_iota(str(RESUME)), [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(2.0)])
    assert story(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, mode(0.1)),
        (2.0, "mdl_command", None, mode(0.1)),                     # the restarted interpreter gets it again
        (5.0, "commit", 0, None), (5.0, "ack", 0, "COMMIT")]      # 2 + (5 - 2): no time lost or added
    assert not violations(engine)


def test_a_restart_within_the_switching_time_of_the_last_command_resends_once_it_allows():
    engine = run(load_iota(str(RESUME)), [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(0.4)])
    sent = [(t, value) for t, action, _, value in story(engine) if action == "mdl_command"]
    assert sent == [(0.0, mode(0.1)), (1.0, mode(0.1))]          # mdl_command's switching time is 1
    assert acks(engine) == [(5.6, 0, "COMMIT")]    # 1.0 + (5 - 0.4): the 0.6 s waiting is not signalling
    assert not violations(engine)


def test_a_restart_notice_when_nothing_is_signalled_changes_nothing():
    quiet = run(load_iota(str(RESUME)), [restart(1.0), req(2.0, 0, 1, epoch=2.0, w=0.3), restart(6.0)])
    plain = run(load_iota(str(RESUME)), [req(2.0, 0, 1, epoch=2.0, w=0.3)])
    assert story(quiet) == story(plain) == [
        (2.0, "schedule", 0, None), (2.0, "mdl_command", None, mode(0.3)),
        (4.0, "commit", 0, None), (4.0, "ack", 0, "COMMIT")]


def test_the_conveyor_scheduler_resends_its_program_too():
    engine = run(load_iota(str(EXAMPLES / "conveyor" / "resume_program.iota")),
                 [req(0.0, 1, 5, epoch=4.0, w=0.7), restart(1.5)])
    sent = [(t, value) for t, action, _, value in story(engine) if action == "mdl_command"]
    assert [t for t, _ in sent] == [0.0, 1.5] and sent[0][1] == sent[1][1]
    assert acks(engine) == [(4.0, 1, "COMMIT")]
    assert not violations(engine)


def test_runs_with_restart_notices_at_random_times_conform(tmp_path):
    inputs = [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(0.7), req(1.0, 1, 5, epoch=2.0, w=0.9), restart(2.2),
              restart(3.5), restart(4.0, "mdl_command")]
    for seed in range(3):
        assert_conforms(lambda: load_iota(str(RESUME)), inputs, 15.0, seed, tmp_path)
