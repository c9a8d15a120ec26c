"""A system file's `time_unit` makes the IOTAs count time in its units (t = 3 is 6 s with a unit
of 2 s). The Buggy picture and `iotad candump` show and select seconds, as their labels say."""
import pytest

from buggy_runs import ROOT, run_virtual
from iotad.cli.commands.candump import frame_events
from sim.worlds.buggy_plot import buggy_data
from iotad.recording.mcap_reader import read_recording


@pytest.fixture(scope="module")
def slow_units(tmp_path_factory):
    folder = tmp_path_factory.mktemp("units")
    text = (ROOT / "examples" / "buggy.toml").read_text()
    text = text.replace('name = "buggy"\n', 'name = "buggy"\ntime_unit = 2.0\n', 1)
    text = text.replace('"buggy/', f'"{ROOT}/examples/buggy/')
    (folder / "buggy.toml").write_text(text)
    return read_recording(run_virtual(str(folder / "buggy.toml"), 6, folder / "units.mcap"))


def test_the_recording_says_its_time_unit(slow_units):
    assert slow_units.time_unit == 2.0
    assert max(e["t"] for e in slow_units.trace()) == pytest.approx(3.0)  # spec units


def test_the_picture_shows_seconds(slow_units):
    path = buggy_data(slow_units)["path"]
    assert path[-1][0] - path[0][0] == pytest.approx(6.0, abs=0.25)


def test_candump_shows_and_selects_seconds(slow_units):
    frames = frame_events(slow_units, "tx")
    assert frames[-1][0] == pytest.approx(6.0, abs=0.05)
    late = frame_events(slow_units, "tx", start=5.0)
    assert late and all(t >= 5.0 for t, *_ in late) and len(late) < len(frames) / 4
