"""Buggy's deciders tick after its sensing chain (choose 20 ms, buggy 30 ms after each reading), so
that any firing its windows allow decides on the readings of the same period: under a random
schedule every decision follows the newest proximity, food and conscious command by less than half
a period, and the latest schedule takes the eager one's decisions. (When both ticked at the
reading's instant, a random firing decided on readings 0.1 s old, where the eager one decided on
fresh ones; the first setpoints already differed, and 3 of 20 seeds ran Buggy into walls:
docs/stress.md.)"""
import pytest
from buggy_runs import outputs, run_virtual

SECONDS = 10.0


@pytest.fixture(scope="module")
def latest_run(tmp_path_factory):
    return run_virtual("buggy.toml", SECONDS, tmp_path_factory.mktemp("latest") / "latest.mcap",
                       "--policy", "latest")


@pytest.fixture(scope="module")
def random_run(tmp_path_factory):
    return run_virtual("buggy.toml", SECONDS, tmp_path_factory.mktemp("random") / "random.mcap",
                       "--policy", "random:6")


def ages_at_each_decision(recording) -> list[tuple[float, dict[str, float]]]:
    """(t, {input: its age}) at each of buggy's moods: how old the newest of each input it reads was."""
    newest: dict[str, float] = {}
    ages = []
    for t, node, channel, _ in outputs(recording):
        if node == "body" and channel in ("proximity", "food"):
            newest[channel] = t
        elif node == "conscious/c" and channel == "cmd":
            newest["conscious"] = t
        elif node == "buggy" and channel == "mood" and len(newest) == 3:
            ages.append((t, {name: t - seen for name, seen in newest.items()}))
    return ages


@pytest.mark.parametrize("run", ["random_run", "latest_run", "buggy_run"])
def test_every_decision_reads_the_readings_of_its_own_period(run, request):
    ages = ages_at_each_decision(request.getfixturevalue(run))
    assert len(ages) >= 10 * SECONDS - 2
    stale = [(round(t, 4), age) for t, age in ages if max(age.values()) >= 0.05]
    assert not stale, stale[:3]


def test_the_latest_firing_makes_the_eager_decisions(latest_run, buggy_run):
    def decisions(recording):
        return [(v["active"], v["doing"]) for t, _, _, v in outputs(recording, "mood") if t <= SECONDS]
    latest, eager = decisions(latest_run), decisions(buggy_run)
    assert len(latest) >= 10 * SECONDS - 1 and {d for d in eager} > {("CONSCIOUS", "WANDER")}
    assert latest == eager[:len(latest)]
