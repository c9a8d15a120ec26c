"""Where a run parts from the eager run (iotad/recording/divergence.py): the k-th output of a
channel against the k-th of the same channel, timing alone no difference; the earliest decision
is the earliest difference on a channel the eager run used at most once a second."""
from iotad.cli import main
from iotad.recording.divergence import NONE, Difference, differences, first_decision, first_per_node
from late_watchdog import write_system


def test_outputs_are_paired_by_count_and_a_run_that_stops_short_is_named(tmp_path):
    system = write_system(tmp_path)
    runs = {}
    for policy in ("eager", "latest"):
        runs[policy] = tmp_path / f"{policy}.mcap"
        assert main(["run", str(system), "--virtual", "--until", "2", "-o", str(runs[policy]), "--plain",
                     "--policy", policy]) == 0
    # eager against itself: no difference, though every firing is at its own time
    assert differences(runs["eager"], runs["eager"]) == []
    found = differences(runs["latest"], runs["eager"])
    late = next(d for d in found if d.action == "late")
    assert (late.iota, late.count, late.t, late.value, late.reference_t, late.reference_value) == \
        ("watchdog", 0, 0.65, 1, 0.1, 0)
    # the sender's pings are the same numbers, later: the latest run makes fewer in 2 s, and the
    # first it never made is named at the eager run's time
    ping = next(d for d in found if d.action == "ping")
    assert (ping.t, ping.value, ping.count, ping.reference_value) == (None, NONE, 3, 3)
    assert ping.reference_t == 0.4 and [d.iota for d in found] == ["sender", "watchdog"]  # by time: 0.4, 0.65
    assert [d.iota for d in first_per_node(found)] == ["sender", "watchdog"]


def test_the_earliest_decision_skips_channels_of_many_outputs_a_second():
    stream = Difference("arm/motor", "joint_states", None, 0, 0.02, [1.0], 0.02, [0.9], reference_outputs=7500)
    ack = Difference("arm/scheduler", "ack", 1, 0, 3.4, "REJECT", 2.3, "COMMIT", reference_outputs=2)
    never = Difference("arm/scheduler", "mdl_command", None, 1, None, NONE, 1.3, {"id": "dodge"}, reference_outputs=3)
    assert first_decision([stream, never, ack], span=150.0) is ack
    assert first_decision([stream], span=150.0) is None
    assert "never output in this run" in never.line() and "the reference's was 'COMMIT' at t=2.3000 s" in ack.line()
