"""The bad day's bound on cubes (tests/bad_day_reading.py, `impaired_share`): the share of the
campaign during which the link of arm or camera was cut, or slowed below what the cell's traffic
across hosts needs (256 kbit/s, measured). The cell cannot pick through those by design, so the
bench prints the share left beside the cubes. Faults that overlap count once; a link slowed to what
still carries the cell, a kill and a stop take no link; a fault that could not be made takes nothing."""
from types import SimpleNamespace

import pytest

from bad_day_reading import impaired_share
from bad_day_run import Done
from fault_schedule import Fault

S = 1_000_000_000


def made(at: float, kind: str, host: str, duration: float, missed: str = "", rate: str = "64kbit") -> Done:
    return Done(Fault(at, kind, host, duration, "node:sim" if kind in ("kill", "stop") else "",
                      rate if kind == "slow" else ""), int(at * S), int((at + duration) * S), missed=missed)


def test_overlapping_cuts_and_slowdowns_count_once_and_kills_stops_and_missed_faults_not_at_all():
    done = [made(10, "partition", "arm", 20),     # 10-30
            made(25, "slow", "camera", 10),       # 25-35: overlaps, adds 5
            made(50, "kill", "arm", 0),
            made(60, "stop", "camera", 2),
            made(70, "slow", "arm", 10, missed="no such link")]
    campaign = SimpleNamespace(done=done, length=100.0)
    assert impaired_share(campaign) == 0.25


@pytest.mark.parametrize("rate, counts", [("64kbit", True), ("255kbit", True), ("256kbit", False),
                                          ("1mbit", False), ("0.2mbit", True)])
def test_a_link_slowed_to_what_still_carries_the_cell_takes_nothing(rate, counts):
    campaign = SimpleNamespace(done=[made(10, "slow", "arm", 20, rate=rate)], length=100.0)
    assert impaired_share(campaign) == (0.2 if counts else 0.0)


def test_a_campaign_without_link_faults_has_its_links_whole():
    assert impaired_share(SimpleNamespace(done=[made(5, "kill", "arm", 0)], length=60.0)) == 0.0
