"""`--seed` fires every action at a random time inside its window: any schedule the specs allow.
Every output of Buggy's IOTAs has a deadline, so that such a schedule keeps up with the world as
the eager one does: a reading or a command may not wait for ever (before the deadlines, Buggy's
pose went out 7 times in 15 s instead of 150, and it steered on readings seconds old while
`iotad check` passed the run)."""
from buggy_runs import outputs, run_virtual


def test_a_random_schedule_keeps_every_sensor_and_command_on_time(tmp_path):
    recording = run_virtual("buggy.toml", 10, tmp_path / "seeded.mcap", "--seed", "42")
    counts = {}
    for _, node, channel, _ in outputs(recording):
        counts[(node, channel)] = counts.get((node, channel), 0) + 1
    # one reading each sense period and one command each tick (both 0.1 s here), as in an eager run
    for key in [("body", "pose"), ("body", "proximity"), ("body", "food"), ("body", "crack")]:
        assert counts[key] in (99, 100), (key, counts[key])
    assert counts[("buggy", "setpoints")] in (99, 100), counts[("buggy", "setpoints")]
    poses = [value for _, _, _, value in outputs(recording, "pose")]
    assert abs(poses[-1]["x"] - poses[0]["x"]) + abs(poses[-1]["y"] - poses[0]["y"]) > 0.5  # it went somewhere
