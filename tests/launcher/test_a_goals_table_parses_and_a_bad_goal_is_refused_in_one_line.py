"""A system file's `[goals]`: conditions over the run's metrics, parsed (never evaluated as
Python) by the declaration; a goal that does not parse is refused in one line naming it."""
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.launcher.system.declaration import parse_declaration
from iotad.launcher.goals import Goal, judge, parse_goal, GoalError

ROOT = Path(__file__).resolve().parents[2]
HEAD = (f'[system]\nname = "fig"\n\n[[node]]\nname = "scheduler"\nspec = "{ROOT / "nodes/scheduler/scheduler.iota"}"\n'
        f'params = {{ N = 2, T = 0.5 }}\n\n[sweep]\nmetrics = "{ROOT / "examples/figure2_metrics.py"}:ack_metrics"\n')


def test_goals_parse_into_metric_comparison_and_number():
    declaration = parse_declaration(HEAD + '\n[goals]\ncommits = ">= 3"\nviolations = "== 0"\nrejects = "<1.5e1"\n')
    assert list(declaration.errors) == []
    assert declaration.goals == (Goal("commits", ">=", 3.0), Goal("violations", "==", 0.0), Goal("rejects", "<", 15.0))
    assert [str(goal) for goal in declaration.goals] == ["commits >= 3", "violations == 0", "rejects < 15"]


def test_a_goal_is_judged_on_the_metrics_and_one_not_measured_is_a_miss():
    goals = [Goal("placed", ">=", 18), Goal("violations", "==", 0), Goal("bumps", "==", 0)]
    verdicts = judge(goals, {"placed": 17, "violations": 0})
    assert [verdict.held for verdict in verdicts] == [False, True, None]
    assert [verdict.line() for verdict in verdicts] == [
        "placed >= 18: MISSED (17)", "violations == 0: held (0)",
        "bumps == 0: NOT MEASURED (the run has no metric 'bumps')"]


@pytest.mark.parametrize("condition", ['">= lots"', '"__import__(\'os\').system(\'true\')"', '"placed >= 18"',
                                       '"=> 3"', '">= nan"', '">= inf"', "18", '""'])
def test_a_bad_goal_is_refused_in_one_line_that_names_it(tmp_path, capsys, condition):
    system = tmp_path / "fig.toml"
    system.write_text(HEAD + f"\n[goals]\ncommits = {condition}\n")
    assert main(["run", "--check", str(system)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "[goals] commits" in err and "not a condition" in err


def test_a_goal_over_a_metric_no_hook_measures_is_refused():
    declaration = parse_declaration(HEAD.split("[sweep]")[0] + '\n[goals]\nplaced = ">= 18"\nviolations = "== 0"\n')
    assert len(declaration.errors) == 1 and "[goals]: placed is measured by no [sweep] metrics hook" in declaration.errors[0]
    assert parse_declaration(HEAD.split("[sweep]")[0] + '\n[goals]\nviolations = "== 0"\n').errors == ()


def test_a_goal_key_must_be_a_metric_name():
    with pytest.raises(GoalError, match=r"\[goals\] 'a b'"):
        parse_goal("a b", ">= 1")


def test_until_says_how_long_a_run_the_goals_are_stated_for():
    declaration = parse_declaration(HEAD + '\n[goals]\nuntil = 20\ncommits = ">= 3"\n')
    assert list(declaration.errors) == [] and declaration.goals_until == 20.0 and len(declaration.goals) == 1
    bad = parse_declaration(HEAD + '\n[goals]\nuntil = "long"\n')
    assert len(bad.errors) == 1 and "[goals] until = \"long\"" in bad.errors[0]
