"""Buggy finds food (hunger falls while it eats), and never leaves the arena whatever drives it."""
from buggy_runs import outputs


def test_reaches_food_and_hunger_falls_while_eating(buggy_run):
    eaten = [v for _, _, _, v in outputs(buggy_run, "landmark") if v["kind"] == "EATEN"]
    assert len(eaten) >= 2
    moods = [(t, v) for t, _, _, v in outputs(buggy_run, "mood")]
    food = {round(t, 6): v for t, _, _, v in outputs(buggy_run, "food")}
    falls = [(a, b) for (_, a), (t, b) in zip(moods, moods[1:]) if b["hunger"] < a["hunger"]]
    rises = [(a, b) for (_, a), (t, b) in zip(moods, moods[1:]) if b["hunger"] > a["hunger"]]
    assert falls and rises
    assert all(b["doing"] == "EAT" or a["doing"] == "EAT" for a, b in falls)  # hunger falls only on eating
    assert any(food.values())


def test_never_leaves_the_arena(buggy_run, hungry_run):
    for run in (buggy_run, hungry_run):
        walls = next(v for _, _, _, v in outputs(run, "landmark") if v["kind"] == "WALL")
        limit = walls["x2"] - 0.1  # Buggy's body radius
        poses = [v for _, _, _, v in outputs(run, "pose")]
        assert len(poses) > 800
        assert all(abs(p["x"]) <= limit + 1e-9 and abs(p["y"]) <= limit + 1e-9 for p in poses)
    # the hungry Buggy did push against the walls: the arena held it
    assert poses[-1]["bumps"] > 0
