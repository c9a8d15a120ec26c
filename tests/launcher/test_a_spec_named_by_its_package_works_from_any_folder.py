"""`spec = "nodes.scheduler:scheduler.iota"` names a shipped spec by its Python package, so a
system file in any folder runs it without a path to the repository; a package or file that does
not exist is one line naming the entry."""
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]


def figure2_in(folder: Path, spec: str) -> Path:
    text = (ROOT / "examples/figure2.toml").read_text()
    text = text.replace('spec = "../nodes/scheduler/scheduler.iota"', f'spec = "{spec}"')
    text = text.replace('python = "requesters.py:', f'python = "{ROOT}/examples/requesters.py:')
    assert f'spec = "{spec}"' in text
    path = folder / "fig2.toml"
    path.write_text(text)
    return path


def test_a_shipped_spec_by_package_name_runs_from_another_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    system = figure2_in(tmp_path, "nodes.scheduler:scheduler.iota")
    assert main(["run", "--check", str(system)]) == 0
    out = tmp_path / "fig2.mcap"
    assert main(["run", str(system), "--virtual", "--until", "5", "-o", str(out), "--plain"]) == 0
    acks = [e for e in read_recording(out).trace("scheduler") if e["action"] == "ack" and e["kind"] == "output"]
    assert acks  # the Figure 2 scheduler answered


def test_a_missing_package_or_file_is_one_line(tmp_path, capsys):
    assert main(["run", "--check", str(figure2_in(tmp_path, "nodes.scheduler:nope.iota"))]) == 2
    assert "spec file 'nodes.scheduler:nope.iota': package 'nodes.scheduler' has no file 'nope.iota'" in \
        capsys.readouterr().err
    assert main(["run", "--check", str(figure2_in(tmp_path, "nodes.nothing_here:scheduler.iota"))]) == 2
    assert "'nodes.nothing_here' is no importable package" in capsys.readouterr().err
