"""The launcher's start gate: every node it starts goes live and waits; once all are live the
launcher opens the gate and their engines start together, so that no engine runs its first
windows while another node still imports on the same cores (those were the deadline misses of a
real-time start). A node restarted later starts its engine at once. Read from the recording."""
import subprocess
import sys
import time
from pathlib import Path

from launcher_helpers import wait_until

from iotad.recording.mcap_reader import read_recording

TESTS = Path(__file__).resolve().parents[1]
# tests/system_iotas.py's Source, going live only once the test says so (a slow start-up): the
# test says so 1.5 s after the fast node is live, so the order holds however loaded the machine
SLOW_NODE = f"""
import sys
import time
from pathlib import Path

# only in the node's own process (`python -m iotad.node_host`): the launcher imports this file too, to
# check the system before it starts anything
deadline = time.monotonic() + 60  # never hang: a test that failed before saying go
while sys.argv[0].endswith("host/__main__.py") and not Path("go").exists() and time.monotonic() < deadline:
    time.sleep(0.02)
sys.path.insert(0, {str(TESTS)!r})
from system_iotas import Source  # noqa: E402
"""
SYSTEM = f"""
[system]
name = "gate"
time_unit = 0.1

[[node]]
name = "fast"
python = "{TESTS / 'system_iotas.py'}:Source"

[[node]]
name = "slow"
python = "slow_node.py:Source"
"""


def test_the_fast_node_waits_for_the_slow_one_and_both_engines_start_after_the_gate(tmp_path):
    (tmp_path / "slow_node.py").write_text(SLOW_NODE)
    (tmp_path / "gate.toml").write_text(SYSTEM)
    recording = tmp_path / "gate.mcap"
    output = tmp_path / "run.out"
    with open(output, "wb") as sink:
        proc = subprocess.Popen([sys.executable, "-m", "iotad", "run", "gate.toml", "--until", "1", "--after-live",
                                 "--port", "0", "--plain", "-o", str(recording)],
                                stdout=sink, stderr=subprocess.STDOUT, cwd=tmp_path, start_new_session=True)
    try:
        assert wait_until(lambda: "fast: live" in output.read_text(), 60), output.read_text()
        time.sleep(1.5)  # the gap the assertions below measure, made here, not hoped for
        (tmp_path / "go").touch()
        assert proc.wait(90) == 0, output.read_text()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert "start gate open: all 2 nodes are live or ended; their engines start now" in output.read_text()

    run = read_recording(recording)
    events = run.launcher_events()
    live = {e["node"]: e["t_ns"] / 1e9 for e in events if e.get("event") == "live"}
    gate = [e["t_ns"] / 1e9 for e in events if e.get("event") == "gate"]
    assert len(gate) == 1 and set(live) == {"fast", "slow"}
    assert live["fast"] < live["slow"] - 1.0 <= gate[0] - 1.0  # the fast node was live long before
    starts = {e["iota"]: e["value"]["wall"] for e in run.trace(starts=True) if e["kind"] == "start"}
    assert set(starts) == {"fast", "slow"}
    assert all(wall >= gate[0] for wall in starts.values())  # no engine before the gate
    assert starts["fast"] - live["fast"] > 1.0              # the fast one waited
    assert abs(starts["fast"] - starts["slow"]) < 1.0       # they started together
    # each sent its outputs from its own start: the fast one none before the slow one was live
    sent = [e for e in run.trace() if e["kind"] == "output"]
    assert {e["iota"] for e in sent} == {"fast", "slow"}
