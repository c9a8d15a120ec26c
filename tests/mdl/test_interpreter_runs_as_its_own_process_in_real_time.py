"""examples/mdl_arm_realtime.toml under `iotad run` in real time: the interpreter is its own
process at 500 Hz, gets the program the scheduler forwards, runs it to its end on the ideal arm,
and the recording holds its ticks, setpoints and atom and program ends. (Real time on a shared
machine: late ticks may be deadline misses; nothing else may go wrong.)"""
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.recording.mcap_reader import read_recording
from launcher_helpers import ROOT, free_port

SYSTEM = ROOT / "examples" / "mdl_arm_realtime.toml"


def test_a_program_runs_to_its_end_in_real_time(tmp_path):
    out = tmp_path / "rt.mcap"
    done = subprocess.run([sys.executable, "-m", "iotad", "run", str(SYSTEM), "--plain", "--until", "8", "--after-live",
                           "--port", str(free_port()), "-o", str(out), "--log-dir", str(tmp_path / "logs")],
                          capture_output=True, text=True, timeout=90, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    trace = read_recording(out).trace()
    mdl = [e for e in trace if e["iota"] == "mdl"]
    ticks = [e["t"] for e in mdl if e["action"] == "tick" and e["kind"] == "internal"]
    assert len(ticks) > 500
    grid = [int(t / 0.002 + 1e-6) for t in ticks]                 # a late tick belongs to its grid point
    assert all(b > a for a, b in zip(grid, grid[1:]))            # one tick per grid point at most
    [command] = [e for e in mdl if e["action"] == "mdl_command"]
    assert command["value"]["id"] == "reach"
    ends = [(e["value"]["atom"], e["value"]["end"]) for e in mdl if e["action"] == "atom_end"]
    assert ends == [(0, "DONE"), (1, "DONE")], [e for e in mdl if e["action"] in ("fault", "atom_end")][:5]
    [end] = [e["value"] for e in mdl if e["action"] == "program_end"]
    assert (end["program"], end["end"]) == ("reach", "DONE")
    # 650 ticks (1.3 s) from the first tick after the command: the next grid point's (650), or
    # the current one's if that tick came late, after the command (649); a tick more than a
    # period late on a busy machine steps by the ticks that passed, and may end it that late (but
    # never earlier: the tick a program starts at is one step, however late it came)
    assert 649 <= end["tick"] - int(command["t"] / 0.002 + 1e-6) <= 675
    assert end["t"] - command["t"] == pytest.approx(1.3, abs=0.05)
    last = [e["value"]["position"] for e in mdl if e["action"] == "setpoints"][-1]
    assert last[:3] == pytest.approx([0.8, 0.3, -0.6])
    other = [e for e in trace if e["kind"] == "violation" and e["value"]["violation"] != "deadline_miss"]
    assert not other, other[:5]
