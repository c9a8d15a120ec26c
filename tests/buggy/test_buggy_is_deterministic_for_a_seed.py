"""The same system file and seed give the same run: every recorded output, value and time."""
from buggy_runs import outputs, run_virtual


def test_two_virtual_runs_record_identical_values(tmp_path):
    first = outputs(run_virtual("buggy.toml", 20, tmp_path / "a.mcap"))
    second = outputs(run_virtual("buggy.toml", 20, tmp_path / "b.mcap"))
    assert len(first) > 1000
    assert first == second
    poses = [v for _, node, channel, v in first if channel == "pose"]
    assert len({(round(p["x"], 3), round(p["y"], 3)) for p in poses}) > 50  # it moved
