"""A new command preempts the running program at the next tick; sending the preempted program
again resumes it where it stopped (atom, time spent in it), so it finishes the trajectory it
would have finished, shifted by the interruption (the paper, section 2)."""
import pytest

from channels.mdl import hold, minimum_jerk, program, ramp

REACH = program("A", minimum_jerk({"joint1": 0.6}, T=1.0), hold(T=0.2))
STOP = program("B", hold())


def trajectory(run):
    return {round(t * 100): p for t, p in run.setpoints(0)}


def test_a_resumed_program_finishes_the_same_trajectory_shifted_by_the_interruption(make_run):
    alone = make_run()
    alone.command(REACH, t=0.0)
    alone.run(until=2.0)
    base = trajectory(alone)

    run = make_run()
    run.command(REACH, t=0.0)
    run.command(STOP, t=0.3005)      # preempts A at tick 31
    run.command(REACH, t=0.7005)     # resumes A at tick 71
    run.run(until=2.0)
    got = trajectory(run)
    assert [got[m] for m in range(1, 31)] == [base[m] for m in range(1, 31)]
    assert {got[m] for m in range(31, 71)} == {base[30]}           # held while B ran
    shift = 40
    assert [got[m] for m in range(71, 121 + shift)] == pytest.approx([base[m - shift] for m in range(71, 121 + shift)],
                                                                     abs=1e-12)
    ends = [(v["program"], v["end"], v["behaviour"], v["atom"], v["tick"]) for v in run.values("program_end")]
    assert ends == [("A", "PREEMPTED", 0, 0, 31), ("B", "PREEMPTED", 0, 0, 71), ("A", "DONE", 0, 1, 120 + shift)]
    reach_end = run.values("atom_end")[0]
    assert (reach_end["program"], reach_end["tick"], reach_end["elapsed"]) == ("A", 100 + shift, pytest.approx(1.0))


def test_a_program_resumed_elsewhere_moves_on_smoothly_and_keeps_its_goal_and_time(make_run):
    run = make_run()
    run.command(REACH, t=0.0)
    run.command(program("away", ramp({"joint1": -0.2}, T=0.2), hold()), t=0.3005)
    run.command(REACH, t=0.7005)
    run.run(until=2.0)
    got = trajectory(run)
    assert got[70] == pytest.approx(-0.2)
    steps = [abs(got[m + 1] - got[m]) for m in range(70, 140)]
    assert max(steps) < 0.02                                     # no jump when A takes over again
    assert got[140] == pytest.approx(0.6, abs=1e-12)             # the goal, after the rest of its T
    reach_end = run.values("atom_end")[1]
    assert (reach_end["program"], reach_end["end"], reach_end["tick"]) == ("A", "DONE", 140)


def test_the_same_program_sent_while_it_runs_goes_on_undisturbed(make_run):
    run = make_run()
    run.command(REACH, t=0.0)
    run.command(REACH, t=0.5005)
    run.run(until=1.5)
    assert [(v["program"], v["end"], v["tick"]) for v in run.values("program_end")] == [("A", "DONE", 120)]


def test_a_different_program_under_the_same_id_starts_afresh(make_run):
    run = make_run()
    run.command(REACH, t=0.0)
    run.command(STOP, t=0.3005)
    changed = program("A", minimum_jerk({"joint1": 0.3}, T=1.0))
    run.command(changed, t=0.5005)
    run.run(until=2.0)
    ends = [(v["program"], v["end"], v["tick"]) for v in run.values("program_end")]
    assert ends[-1] == ("A", "DONE", 150)                        # a whole T from tick 51
    assert trajectory(run)[150] == pytest.approx(0.3)


def test_only_the_last_max_suspended_programs_are_kept(make_run):
    run = make_run(max_suspended=1)
    run.command(REACH, t=0.0)
    run.command(STOP, t=0.3005)                                  # A kept
    run.command(program("C", hold()), t=0.4005)                  # B kept, A forgotten
    run.command(REACH, t=0.5005)                                 # A starts over
    run.run(until=2.0)
    reach_end = [v for v in run.values("atom_end") if v["program"] == "A"][0]
    assert reach_end["tick"] == 51 + 99 and reach_end["elapsed"] == pytest.approx(1.0)


def test_a_command_replaced_before_the_next_tick_never_runs(make_run):
    run = make_run()
    run.command(REACH, t=0.0101)
    run.command(STOP, t=0.0151)
    run.run(until=0.1)
    assert [(v["program"], v["end"], v["tick"]) for v in run.values("program_end")] == [("A", "PREEMPTED", 1)]
    assert {p for _, p in run.setpoints(0)} == {0.0}


def test_a_resumed_move_leaves_the_joints_it_does_not_name_where_another_program_put_them(make_run):
    run = make_run()
    run.command(REACH, t=0.0)                                            # names joint1 only
    run.command(program("wrist", ramp({"joint5": 0.4}, T=0.2), hold()), t=0.3005)
    run.command(REACH, t=0.7005)
    run.run(until=2.0)
    final = run.of("setpoints", "output")[-1]["value"]["position"]
    assert final[0] == pytest.approx(0.6, abs=1e-12)                     # REACH's goal
    assert final[4] == pytest.approx(0.4, abs=1e-12)                     # wrist's move stands
