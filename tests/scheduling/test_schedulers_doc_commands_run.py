"""docs/schedulers.md cannot rot: every `iotad spec run` command it shows runs from the repository
root and gives a trace without violations, and every file its commands name exists."""
import json
import re
import shlex

import pytest

from iotad.cli import main

from scheduling_helpers import ROOT

DOC = ROOT / "docs" / "schedulers.md"


def doc_commands():
    blocks = re.findall(r"```sh\n(.*?)```", DOC.read_text(), flags=re.S)
    return [shlex.split(line)[1:] for block in blocks for line in block.splitlines() if line.startswith("iotad ")]


SPEC_RUNS = [argv for argv in doc_commands() if argv[:2] == ["spec", "run"]]


def test_the_doc_shows_each_scheduler_running():
    shown = " ".join(" ".join(argv) for argv in doc_commands())
    for path in ("nodes/scheduler/resume.iota", "nodes/scheduler/fusion.iota", "nodes/scheduler/subsumption.iota",
                 "examples/priority-tree4.iota", "examples/behaviours.iota", "examples/resume.toml",
                 "examples/fusion.toml", "examples/subsumption.toml"):
        assert path in shown, path
    for argv in doc_commands():
        for before, arg in zip([None, *argv], argv):
            if re.match(r"^(examples|nodes)/", arg) and before != "--title":
                assert (ROOT / arg).exists(), arg


@pytest.mark.parametrize("argv", SPEC_RUNS, ids=lambda argv: argv[2].split("/")[-1])
def test_documented_spec_runs_run_without_violations(argv, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    assert main(argv) == 0, capsys.readouterr().err
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [e for e in trace if e["kind"] == "output"]
    assert not [e for e in trace if e["kind"] == "violation"]
