"""Dynamic priority: at every control tick buggy lets the subconscious behaviour (avoid walls)
drive when fear exceeds hunger and the conscious one otherwise; a hungry Buggy therefore goes
closer to walls than a fed one before it turns away."""
from buggy_runs import outputs


def moods(run):
    return [v for _, _, _, v in outputs(run, "mood")]


def test_fear_above_hunger_means_avoid_and_below_means_conscious(buggy_run, hungry_run):
    for run in (buggy_run, hungry_run):
        for m in moods(run):
            assert m["active"] == ("SUBCONSCIOUS" if m["fear"] > m["hunger"] else "CONSCIOUS"), m
    seen = moods(buggy_run)
    assert {m["active"] for m in seen} == {"CONSCIOUS", "SUBCONSCIOUS"}
    assert {"WANDER", "FOLLOW", "EAT", "AVOID"} <= {m["doing"] for m in seen}
    # switches both ways, more than once: the limit cycles of the paper's figures
    switches = sum(1 for a, b in zip(seen, seen[1:]) if a["active"] != b["active"])
    assert switches >= 4


def test_a_hungry_buggy_ignores_a_fear_that_would_turn_a_fed_one(hungry_run):
    afraid_but_hungry = [m for m in moods(hungry_run) if m["fear"] > 0.2 and m["active"] == "CONSCIOUS"]
    assert afraid_but_hungry  # hunger outweighed a real fear: the hierarchy is not fixed
    assert all(m["hunger"] >= m["fear"] for m in afraid_but_hungry)
