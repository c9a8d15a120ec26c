"""How the delivery check judges a message its real-time receiver never took, from the
receiver's runs (a start event each, then heartbeats and trace events): before the first start
nobody could take it, between a death and the restart it was lost because the receiver was down
(said so, whatever else it later received), near the end of the last run it was in flight."""
from iotad.recording.delivery_accounts import Life


def echo_life():
    # started at 1, last heard at 4; restarted at 6, last heard at 9
    return Life(starts=[1.0, 6.0], signs=[2.0, 3.0, 4.0, 7.0, 9.0], virtual_end=None)


def test_before_the_first_start_it_is_not_judged():
    verdict, reason = echo_life().judge(0.5, 0.1, "echo")
    assert verdict == "unjudged" and "before echo's engine started (t=1)" in reason
    assert echo_life().before_start(0.5) and not echo_life().before_start(1.5)


def test_while_running_it_is_lost():
    assert echo_life().judge(3.5, 0.1, "echo") == ("lost", "echo was running until t=4")
    assert echo_life().down(3.5, 0.1, "echo") is None


def test_between_a_death_and_the_restart_it_is_lost_because_the_receiver_was_down():
    reason = "sent while echo was down: its last sign of life at t=4, restarted at t=6"
    assert echo_life().judge(5.0, 0.1, "echo") == ("lost", reason)
    assert echo_life().down(5.0, 0.1, "echo") == reason


def test_within_the_grace_of_the_last_sign_of_the_last_run_it_is_in_flight():
    verdict, reason = echo_life().judge(8.95, 0.1, "echo")
    assert verdict == "unjudged" and "in flight when the run ended" in reason
    assert echo_life().down(8.95, 0.1, "echo") is None


def test_virtual_time_has_one_run_and_no_downtime():
    life = Life(starts=[0.0], signs=[], virtual_end=10.0)
    assert life.down(5.0, 0.1, "echo") is None
    assert life.judge(5.0, 0.1, "echo")[0] == "lost"
    assert life.judge(9.95, 0.1, "echo")[0] == "unjudged"


def test_what_a_killed_node_sent_after_its_last_trace_is_untraced_not_unexplained():
    """kill -9 loses a node's last trace period: a frame the bus (or the wire) carries from then
    is the node's, though its trace does not hold it. The run that was going at that time says
    where its trace ends; the next run, after the restart, has its own."""
    from iotad.recording.delivery_accounts import Life

    life = Life(starts=[0.0, 6.0], signs=[1.0, 5.39123, 6.5, 9.0], virtual_end=None)
    assert life.untraced_at(5.4088) == 5.39123   # after run 1's trace, before run 2 started
    assert life.untraced_at(5.0) is None          # inside run 1's trace
    assert life.untraced_at(8.0) is None          # inside run 2's
    assert life.untraced_at(9.5) == 9.0           # after the last run's trace
    assert Life(starts=[0.0], signs=[], virtual_end=3.0).untraced_at(2.0) is None  # virtual: one engine
