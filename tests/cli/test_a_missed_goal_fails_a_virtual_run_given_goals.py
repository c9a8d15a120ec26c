"""`iotad run --virtual` says whether each of the system file's goals held; with `--goals` a
missed one makes the exit status 1 (without it, the run's own status). Figure 2 commits three
requests in 20 s under eager and two under latest (manipulation's second request comes later)."""
from pathlib import Path

from iotad.cli import main

ROOT = Path(__file__).resolve().parents[2]


def figure2_with(tmp_path, goals: str) -> Path:
    text = (ROOT / "examples/figure2.toml").read_text()
    for name in ("../nodes/scheduler/scheduler.iota", "requesters.py", "figure2_metrics.py"):
        text = text.replace(f'"{name}', f'"{(ROOT / "examples" / name).resolve()}')
    text = text.split("\n[goals]")[0]  # its own goals replaced by the test's
    path = tmp_path / "figure2.toml"
    path.write_text(text + f"\n[goals]\n{goals}\n")
    return path


def test_each_goal_is_said_held_or_missed_and_a_miss_exits_1_with_goals(tmp_path, capsys):
    system = figure2_with(tmp_path, 'commits = ">= 3"\nviolations = "== 0"')
    run = ["run", str(system), "--virtual", "--until", "20", "--plain"]
    assert main([*run, "-o", str(tmp_path / "eager.mcap"), "--goals"]) == 0
    out = capsys.readouterr().out
    assert "goals: 2 of 2 held" in out and "commits >= 3: held (3)" in out and "violations == 0: held (0)" in out
    assert main([*run, "-o", str(tmp_path / "latest.mcap"), "--policy", "latest"]) == 0  # printed, not judged
    assert "commits >= 3: MISSED (2)" in capsys.readouterr().out
    assert main([*run, "-o", str(tmp_path / "latest2.mcap"), "--policy", "latest", "--goals"]) == 1
    assert "goals: 1 of 2 held" in capsys.readouterr().out


def test_goals_needs_a_goals_table_and_policy_and_seed_must_agree(tmp_path, capsys):
    run = ["run", str(ROOT / "examples/resume.toml"), "--virtual", "--until", "1", "--no-record"]
    assert main([*run, "--goals"]) == 2
    assert "has no [goals] table" in capsys.readouterr().err
    assert main([*run, "--policy", "latest", "--seed", "3"]) == 2
    assert "--seed 3 is the seed of the random policy" in capsys.readouterr().err
    assert main([*run, "--policy", "random:2", "--seed", "3"]) == 2
    assert main([*run, "--policy", "sometimes"]) == 2
    assert "unknown policy 'sometimes'" in capsys.readouterr().err
