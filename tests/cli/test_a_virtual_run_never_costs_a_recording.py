"""`iotad run --virtual -o FILE`: input that is wrong is found before FILE is opened (so --force
never loses the old recording to it), a value the wire cannot carry is a recorded violation, a
span the recording's times cannot hold is refused, and a run that breaks off on an error of
iotad itself leaves a recording that says so, which `iotad check` does not pass."""
import json
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.virtual import virtual_run
from iotad.recording.engine_sink import EngineRecorder
from iotad.recording.mcap_reader import read_recording
from iotad.recording.writer_process import RecordingProcess

ROOT = Path(__file__).resolve().parents[2]
REQUEST = {"control": {"w": 0.2, "k": 1.0}, "epoch": 1.0, "timeout": 1.0, "priority": 1}


@pytest.fixture
def solo(tmp_path):
    """The Figure 2 scheduler alone, its requests from an input script."""
    system = tmp_path / "solo.toml"
    system.write_text(f'[system]\nname = "solo"\nexternal = ["scheduler.req[0]", "scheduler.req[1]"]\n\n'
                      f'[[node]]\nname = "scheduler"\nspec = "{ROOT / "nodes/scheduler/scheduler.iota"}"\n'
                      f'params = {{ N = 2, T = 0.5 }}\n')
    return system


def script(tmp_path, *lines: dict) -> Path:
    path = tmp_path / "inputs.jsonl"
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def virtual(system, out, *more) -> list[str]:
    return ["run", str(system), "--virtual", "--until", "3", "-o", str(out), "--plain", *more]


def test_an_input_for_no_node_is_refused_before_the_old_recording_is_replaced(solo, tmp_path, capsys):
    out = tmp_path / "kept.mcap"
    assert main(virtual(solo, out)) == 0
    before = out.read_bytes()
    inputs = script(tmp_path, {"t": 0.5, "iota": "nosuch", "action": "req", "index": 0, "value": REQUEST})
    assert main(virtual(solo, out, "--inputs", str(inputs), "--force")) == 2
    assert "no node 'nosuch' in this system (nodes: scheduler" in capsys.readouterr().err
    assert out.read_bytes() == before
    fresh = tmp_path / "fresh.mcap"
    assert main(virtual(solo, fresh, "--inputs", str(inputs))) == 2
    assert not fresh.exists()  # no stray empty recording either


def test_an_external_input_is_named_as_the_system_file_names_it(solo, tmp_path, capsys):
    out = tmp_path / "external.mcap"
    inputs = script(tmp_path, {"t": 0.5, "action": "scheduler.req[1]", "value": REQUEST},
                    {"t": 2.0, "action": "scheduler.req", "index": 0, "value": REQUEST})
    assert main(virtual(solo, out, "--inputs", str(inputs))) == 0
    recorded = [(e["t"], e["index"]) for e in read_recording(out).trace("scheduler")
                if e["kind"] == "input" and e["action"] == "req"]
    assert recorded == [(0.5, 1), (2.0, 0)]
    # one that is not external, without its node, is refused before anything runs
    wrong = script(tmp_path, {"t": 0.5, "action": "req", "index": 0, "value": REQUEST})
    assert main(virtual(solo, tmp_path / "never.mcap", "--inputs", str(wrong))) == 2
    assert ('{"action": "req"} without "iota" must be one of the system\'s external inputs '
            '(scheduler.req[0], scheduler.req[1])') in capsys.readouterr().err
    assert not (tmp_path / "never.mcap").exists()


@pytest.mark.parametrize("priority", [10**26, -(1 << 63) - 1, 1 << 64])
def test_an_int_beyond_64_bits_is_a_recorded_violation(solo, tmp_path, capsys, priority):
    out = tmp_path / "big.mcap"
    inputs = script(tmp_path, {"t": 0.5, "iota": "scheduler", "action": "req", "index": 0, "value": {**REQUEST, "priority": priority}},
                    {"t": 1.0, "iota": "scheduler", "action": "req", "index": 1, "value": REQUEST})
    assert main(virtual(solo, out, "--inputs", str(inputs))) == 0
    recording = read_recording(out)
    assert recording.complete
    violations = recording.violations()
    assert len(violations) == 1 and violations[0]["value"]["violation"] == "bad_value"
    assert f"mdlReq.priority: {priority} does not fit in 64 bits" in violations[0]["value"]["message"]
    # the request that fits is taken and answered
    assert any(e["kind"] == "output" and e["action"] == "ack" for e in recording.trace("scheduler"))


def test_a_span_beyond_the_recordings_times_is_refused(solo, tmp_path, capsys):
    out = tmp_path / "long.mcap"
    assert main(["run", str(solo), "--virtual", "--until", "1e11", "-o", str(out), "--plain"]) == 2
    assert "a recording holds at most 1.84e+10 s" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("writer", ["in this process", "a second process"])
def test_a_run_broken_off_by_an_error_of_iotad_says_so_and_does_not_pass(solo, tmp_path, capsys, monkeypatch, writer):
    out = tmp_path / "broken.mcap"
    inputs = script(tmp_path, *({"t": 0.5 * k, "iota": "scheduler", "action": "req", "index": k % 2, "value": REQUEST} for k in range(6)))
    # the sink that fails: the recorder itself, or what hands events to the writer process
    sink = EngineRecorder if writer == "in this process" else RecordingProcess
    monkeypatch.setattr(virtual_run, "cores", lambda: 1 if writer == "in this process" else 2)
    written = sink.__call__
    seen = []

    def failing(self, event):
        seen.append(event)
        if len(seen) == 6:
            raise RuntimeError("a recorder fault")
        written(self, event)

    monkeypatch.setattr(sink, "__call__", failing)
    assert main(virtual(solo, out, "--inputs", str(inputs))) == 1
    assert "RuntimeError: a recorder fault" in capsys.readouterr().err
    monkeypatch.undo()
    recording = read_recording(out)
    assert recording.complete and len(recording.trace("scheduler")) == 5  # what came before is kept
    assert recording.run_error.startswith("RuntimeError: a recorder fault at t=")
    assert main(["info", str(out)]) == 0
    assert "the run BROKE OFF with an error of iotad: RuntimeError: a recorder fault" in capsys.readouterr().out
    assert main(["check", str(out)]) == 1
    said = capsys.readouterr().out
    assert "BROKE OFF" in said and "PROBLEMS FOUND (the run broke off)" in said


INTERRUPTING = """
from iotad import Internal, Iota


class Interrupting(Iota):
    tick = Internal()

    def init(self):
        self.ticks = 0

    @tick.action(after=0.5)
    def ticked(self):
        self.ticks += 1
        if self.ticks == 3:
            raise KeyboardInterrupt  # node code's own, at t=1.5: no Ctrl-C was pressed
"""


def test_a_keyboard_interrupt_raised_by_node_code_is_no_ctrl_c(tmp_path, capsys):
    (tmp_path / "interrupting.py").write_text(INTERRUPTING)
    system = tmp_path / "interrupting.toml"
    system.write_text('[system]\nname = "interrupting"\n\n[[node]]\nname = "n"\npython = "interrupting.py:Interrupting"\n')
    out = tmp_path / "interrupting.mcap"
    assert main(virtual(system, out)) == 1  # not 130: nobody interrupted the run
    err = capsys.readouterr().err
    assert "a node's code raised KeyboardInterrupt (no Ctrl-C was pressed) at t = 1.500 s; the run broke off" in err
    assert "Ctrl-C at" not in err
    recording = read_recording(out)
    assert recording.run_error.startswith("a node's code raised KeyboardInterrupt (no Ctrl-C was pressed)")
