"""Shared test set-up for every folder: the examples folder and this folder's helper modules
(launcher_helpers, node_harness, recorded_systems, system_iotas) are importable, and the `hub`
fixture gives a test its own zenoh peer."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT / "examples", ROOT / "tests"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))


@pytest.fixture
def hub():
    """A node_harness.Hub: the test's own zenoh peer, where nodes connect; closed after the test."""
    from node_harness import Hub

    hub = Hub()
    try:
        yield hub
    finally:
        hub.close()


# The longest files first. `make test` hands files to its workers (pytest-xdist, --dist loadfile)
# in the order collected; a long file collected late (tests/scaffold's, about 150 s, comes after
# most folders) runs on alone at the end while the other workers have nothing left. Started
# first, the short files fill in around them. Only the order: a file not named keeps its place
# after these. Seconds from `pytest --durations` on this 2-core machine.
LONGEST_FIRST = (
    "tests/scaffold/test_iotad_new_makes_robots_that_run_check_and_show.py",                     # ~150
    "tests/hosts/test_a_short_bad_day_leaves_the_motors_safe_and_every_gap_named.py",            # ~90
    "tests/conveyor/test_conveyor_arm_picks_off_the_belt_in_virtual_time.py",                    # ~70
    "tests/hosts/test_a_host_cut_past_the_lease_holds_up_no_publisher_on_the_others.py",         # ~55
    "tests/hosts/test_with_three_hosts_a_cut_of_one_leaves_the_other_two_talking.py",            # ~55
    "tests/hosts/test_one_run_starts_every_host_through_its_agent.py",                           # ~50
    "tests/hosts/test_a_partition_longer_than_the_lease_heals_and_both_sides_recorded_it.py",    # ~50
    "tests/conveyor/test_conveyor_arm_runs_as_processes_in_real_time.py",                        # ~40
)


def pytest_collection_modifyitems(config, items):
    rank = {path: k for k, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))
