"""The program that docs/mdl.md shows is a valid program, and runs on the default interpreter
(the xArm6 and its default sensors) with its pose reached and its interrupts read."""
import json
import re
from pathlib import Path

import pytest

from channels.mdl import MDL_PROGRAM

DOC = Path(__file__).resolve().parents[2] / "docs" / "mdl.md"


def doc_program():
    [block] = re.findall(r"```json\n(.*?)```", DOC.read_text(encoding="utf-8"), re.S)
    return json.loads(block)


def test_the_documented_program_is_valid():
    program = MDL_PROGRAM.from_plain(doc_program())
    assert [b.name for b in program.behaviours] == ["approach", "lift"]
    assert MDL_PROGRAM.from_plain(MDL_PROGRAM.to_plain(program)) == program


def test_the_documented_program_runs(make_run):
    pytest.importorskip("pybullet")
    run = make_run(start=[0.0, -0.3, -0.6, 0.0, 0.9, 0.0])
    run.command(doc_program(), t=0.0)
    for k in range(60):   # the camera sees the target centred; the gripper nears it, then touches
        run.sensor(0, [0.0, 0.0], t=0.05 * k)
        run.sensor(1, [0.2 if k < 50 else 0.04, 0.0], t=0.05 * k)
        run.sensor(2, [0.0, 0.0, 0.0], t=0.05 * k)
    run.run(until=3.0)
    ends = [(e["behaviour"], e["atom"], e["end"], e["level"]) for e in run.values("atom_end")]
    assert ends[:2] == [(0, 0, "DONE", "NONE"), (0, 1, "INTERRUPTED", "ATOM")]
    assert not run.values("fault") and not run.violations()
