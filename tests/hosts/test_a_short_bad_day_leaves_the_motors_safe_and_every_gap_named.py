"""A short bad day: a minute of faults drawn from a fixed seed across three hosts under access
control, and what must hold whatever the machine's speed: after every partition of the arm's
host every axis was made safe (its frames, as the arm recorded them) within the issue's 100 ms of
its last setpoint, and nothing commanded an axis while the arm was cut off; every gap of the
merged recording is named with the fault that caused it; nothing is left running and no
namespace is left afterwards.

The system is the arm of examples/arm_can.toml (tests/bad_day_run.py `arm_over_three_hosts`: the
trajectory on brain, the simulated ODrives, the CAN motor node and their bus on arm, a 10-a-second
source on camera feeding a sink on brain), not the conveyor that bench/bad_day.py runs: the
conveyor over three hosts is seven nodes, a rendering camera and a PyBullet world, more than two
loaded cores hold in real time beside the suite's other worker, and the goals asserted here are
the arm's (the motors) and the recordings'. Seed 42 draws seven faults in 60 s: three partitions
of arm (1.3 to 3.7 s), its link slowed with tc tbf, kill -9 of camera's recorder, two SIGSTOPs of
the motor node (tests/fault_schedule.py). No cut past the lease, no kill of an agent or a launcher
fits in its minute (each needs 15 to 25 s to settle); bench/bad_day.py draws them, and found a
killed host launcher never brought back (docs/failures.md, "A bad day"; since, its agent starts it
again: tests/hosts/test_a_killed_host_part_is_started_again_by_its_agent.py)."""
import pytest

from bad_day_reading import read_campaign
from bad_day_run import HOSTS, Campaign, arm_over_three_hosts
from fault_injection import leftovers
from fault_schedule import draw_schedule
from namespaces import hosts

PORT, NET = 7673, 222
SEED, LENGTH = 42, 60.0
BOUND = 0.1  # s from the motor node's last setpoint to every axis told IDLE (issue 46's goal)

# about 20 s to start three hosts, the minute of faults, 10 s to stop, 30 s to merge and read
pytestmark = pytest.mark.timeout(240)


def test_a_short_bad_day_leaves_the_motors_safe_and_every_gap_named(tmp_path):
    with hosts(*HOSTS, net=NET) as net:
        text, machine = arm_over_three_hosts(net.addresses[("brain", "arm")], PORT, net.addresses["arm"],
                                             net.addresses["camera"], LENGTH)
        schedule = draw_schedule(SEED, LENGTH, machine.nodes, HOSTS[1:], longest_cut=14, recorder_hosts=HOSTS, first=2)
        campaign = Campaign(net, tmp_path, PORT, text, machine, schedule, LENGTH)
        try:
            campaign.start()
            campaign.play()
        finally:
            campaign.stop()
        # no process of the run is left in any namespace once it stopped (those found were killed)
        assert campaign.orphans == {}, campaign.orphans
        assert leftovers(net) == {}
        names = dict(net.names)
    # every namespace removed
    import subprocess
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    assert not any(name in listed for name in names.values()), listed
    output = campaign.output()
    assert "Traceback" not in output, output[-4000:]
    reading = read_campaign(campaign, check=False)
    assert not reading.merge_error, reading.merge_error
    made = [item for item in reading.faults if not item.done.missed]
    assert len(made) == len(schedule), [item.done.missed for item in reading.faults]

    partitions = [item for item in made if item.done.fault.kind == "partition" and item.done.fault.host == "arm"]
    assert len(partitions) == 3
    for item in partitions:
        # every axis safe, on the motor node's own clock within the bound of its last setpoint,
        # and no command reached an axis after it was made safe and before the heal
        assert item.safe is not None and not item.unsafe, (item.done.fault, item.unsafe)
        assert item.silence is not None and item.silence <= BOUND, (item.done.fault, item.silence)
        assert item.commands_while_cut == 0, (item.done.fault, item.commands_while_cut)
    for item in made:
        if item.safe is not None:  # a stop of the motor node: its drives' watchdogs make the axes safe
            assert not item.unsafe, (item.done.fault, item.unsafe)
    # every process a fault stopped or killed, and every node a cut or slowed link held off, was
    # heard again at the hub (the killed recorder: a new file begun) before the run ended
    assert all(item.recovered is not None for item in made if item.touched or item.done.fault.target == "recorder"), \
        [(item.done.fault.describe(), item.recovered) for item in made]
    # every gap of the merge named with the fault that caused it
    unexplained = [gap for gap in reading.gaps if not gap["cause"]]
    assert unexplained == [], unexplained
    print({item.done.fault.describe(): (item.safe, item.silence, item.recovered) for item in made})
    print([(gap["host"], gap["reason"][:60], gap["cause"]) for gap in reading.gaps])
