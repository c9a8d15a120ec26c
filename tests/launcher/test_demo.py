"""The first demo: Figure 2 over zenoh, one process per IOTA, all three answers, recorded."""
import subprocess
import sys

from launcher_helpers import ROOT, free_port


def test_demo_produces_commit_abort_and_reject(tmp_path):
    # cwd is the temp dir, so the recording lands in tmp_path/recordings. The default 20 s: vision's
    # COMMIT comes with its last request, after manipulation's second pick (12.4 s after the
    # nodes start, `iotad demo --virtual`), and on a busy machine the nodes take a few seconds to start.
    result = subprocess.run([sys.executable, "-m", "iotad", "demo", "--plain",
                             "--port", str(free_port())], capture_output=True, text=True, timeout=60,
                            cwd=tmp_path, start_new_session=True)
    out = result.stdout
    assert result.returncode == 0, out + result.stderr
    assert "COMMIT, ABORT and REJECT all happened over zenoh" in out, out
    vision = next(line for line in out.splitlines() if line.strip().startswith("vision ") and "x" in line)
    assert all(answer in vision for answer in ("COMMIT", "ABORT", "REJECT")), out
    assert "scheduler.mdl_command" in out and "violations:" in out
    recordings = list((tmp_path / "recordings").glob("figure2-*.mcap"))
    assert len(recordings) == 1 and recordings[0].stat().st_size > 1000, out


def test_demo_virtual_still_runs():
    result = subprocess.run([sys.executable, "-m", "iotad", "demo", "--virtual"], capture_output=True, text=True,
                            timeout=60, cwd=ROOT)
    assert result.returncode == 0 and "REJECT" in result.stdout and "0 violations" in result.stdout
