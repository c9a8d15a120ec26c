"""An input is recorded as the IOTA received it, in its type's plain form: an int wider than 64
bits given to a float field (an input script, `iotad pub`, a rogue publisher) is recorded as the
float it became. Recorded as given, it broke the run: msgpack cannot carry it."""
from __future__ import annotations

import json
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording

FIGURE2 = Path(__file__).resolve().parents[2] / "nodes" / "scheduler" / "scheduler.iota"
HUGE = 10**30


def test_a_huge_int_for_a_float_field_is_recorded_as_the_float_it_became(tmp_path, capsys):
    system = tmp_path / "s.toml"
    system.write_text(f'[system]\nname = "t"\nexternal = ["scheduler.req[0]", "scheduler.req[1]"]\n'
                      f'[[node]]\nname = "scheduler"\nspec = "{FIGURE2}"\n')
    inputs = tmp_path / "in.jsonl"
    request = {"control": {"w": HUGE, "k": 1}, "epoch": 1, "timeout": 1.0, "priority": 1}
    inputs.write_text(json.dumps({"t": 0.1, "action": "scheduler.req[0]", "value": request}) + "\n")
    out = tmp_path / "run.mcap"
    assert main(["run", str(system), "--virtual", "--until", "3", "--inputs", str(inputs), "-o", str(out)]) == 0
    assert "0 violations" in capsys.readouterr().out
    trace = read_recording(out).trace("scheduler")
    received = [e["value"] for e in trace if e["action"] == "req" and e["kind"] == "input"]
    assert received == [{"control": {"w": 1e30, "k": 1.0}, "epoch": 1.0, "timeout": 1.0, "priority": 1}]
    assert type(received[0]["control"]["w"]) is float and type(received[0]["epoch"]) is float
    sent = [e["value"] for e in trace if e["action"] == "mdl_command" and e["kind"] == "output"]
    assert sent == [{"w": 1e30, "k": 1.0}]
    assert main(["check", str(out)]) == 0
