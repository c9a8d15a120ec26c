"""`iotad plot` draws a robot's own picture from a plug-in registered in the `iotad.pictures`
entry-point group (the paper's robots: beside their worlds in sim/worlds), and names a
registered picture that cannot be used instead of failing or skipping it silently."""
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording import pictures as registry

ROOT = Path(__file__).resolve().parents[2]


def test_the_paper_robots_pictures_are_registered_beside_their_worlds():
    found, problems = registry.pictures()
    assert problems == []
    assert [(name, picture.__name__) for name, picture in found] == [
        ("buggy", "sim.worlds.buggy_plot"), ("conveyor", "sim.worlds.conveyor_plot")]
    assert all(isinstance(picture, registry.Picture) for _, picture in found)


def fake_group(monkeypatch, *entries: tuple[str, str]) -> None:
    points = [EntryPoint(name, value, registry.GROUP) for name, value in entries]
    monkeypatch.setattr(registry, "entry_points", lambda group: points if group == registry.GROUP else [])


def test_a_picture_that_cannot_be_used_is_named_and_the_others_still_load(monkeypatch):
    fake_group(monkeypatch, ("gone", "no_such_module_here"), ("plain", "json"), ("buggy", "sim.worlds.buggy_plot"))
    found, problems = registry.pictures()
    assert [name for name, _ in found] == ["buggy"]
    assert len(problems) == 2
    assert problems[0].startswith("picture 'gone' (no_such_module_here) does not load: ModuleNotFoundError")
    assert problems[1] == "picture 'plain' (json) has no matches() and plot()"


@pytest.fixture(scope="module")
def figure2(tmp_path_factory):
    recording = tmp_path_factory.mktemp("fig2") / "fig2.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "10", "-o", str(recording)]) == 0
    return recording


def test_plot_warns_of_a_broken_picture_and_draws_the_timeline(figure2, tmp_path, monkeypatch, capsys):
    fake_group(monkeypatch, ("gone", "no_such_module_here"))
    out = tmp_path / "fig2.png"
    assert main(["plot", str(figure2), "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "warning: picture 'gone' (no_such_module_here) does not load" in captured.err
    assert f"wrote {out}" in captured.out and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_registered_picture_that_matches_draws_the_run(figure2, tmp_path, monkeypatch, capsys):
    # a plug-in of one's own, matching every recording: plot draws it instead of the timeline
    module = tmp_path / "my_picture.py"
    module.write_text("from pathlib import Path\n"
                      "def matches(recording):\n    return True\n"
                      "def plot(recording, output, title=None):\n"
                      "    Path(output).write_text(f'{recording.system} {title}')\n    return Path(output)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    fake_group(monkeypatch, ("mine", "my_picture"))
    out = tmp_path / "mine.svg"
    assert main(["plot", str(figure2), "-o", str(out), "--title", "T"]) == 0
    assert out.read_text() == "figure2 T" and f"wrote {out}" in capsys.readouterr().out
