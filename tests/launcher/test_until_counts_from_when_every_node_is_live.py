"""`iotad run --until S --after-live`: the S seconds count from the moment every node is live, so
a slow start-up (imports, PyBullet worlds; 10-30 s in user-mode Linux) does not eat the run.
Without it, --until counts from the launch. Both read from the launcher's lines and the recording."""
import subprocess
import sys
from pathlib import Path

from iotad.recording.mcap_reader import read_recording

TESTS = Path(__file__).resolve().parents[1]
# tests/system_iotas.py's Source, going live about 3 s after it is started (a slow start-up)
SLOW_NODE = f"""
import sys
import time

time.sleep(3.0)
sys.path.insert(0, {str(TESTS)!r})
from system_iotas import Source  # noqa: E402
"""


def run_slow_system(tmp_path, *extra):
    (tmp_path / "slow_node.py").write_text(SLOW_NODE)
    system = tmp_path / "slow.toml"
    # time_unit 0.1: Source sends every 0.1 s
    system.write_text('[system]\nname = "slow"\ntime_unit = 0.1\n\n[[node]]\nname = "slow"\n'
                      'python = "slow_node.py:Source"\n')
    recording = tmp_path / "slow.mcap"
    result = subprocess.run([sys.executable, "-m", "iotad", "run", str(system), "--until", "1", *extra,
                             "--port", "0", "--plain", "-o", str(recording)],
                            capture_output=True, text=True, timeout=90, cwd=tmp_path, start_new_session=True)
    sent = [e for e in read_recording(recording).trace() if e.get("node") == "slow" and e.get("kind") == "output"]
    return result, sent


def test_after_live_gives_the_run_its_seconds_once_every_node_is_live(tmp_path):
    result, sent = run_slow_system(tmp_path, "--after-live")
    lines = result.stdout.splitlines()
    assert result.returncode == 0, result.stdout + result.stderr
    live = next(k for k, line in enumerate(lines) if "every node is live: --until 1 s counts from now" in line)
    stop = next(k for k, line in enumerate(lines) if "--until 1 s after every node was live reached: stopping" in line)
    assert live < stop
    assert len(sent) >= 3, result.stdout  # about ten, one every 0.1 s of its second


def test_without_it_the_seconds_count_from_the_launch(tmp_path):
    result, sent = run_slow_system(tmp_path)
    assert "--until 1 s reached: stopping" in result.stdout, result.stdout + result.stderr
    assert "every node is live" not in result.stdout
    assert sent == []  # stopped while it was still starting
