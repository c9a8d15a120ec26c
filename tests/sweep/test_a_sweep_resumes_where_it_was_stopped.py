"""A sweep stopped by Ctrl-C keeps the runs it finished; the same command again runs only the
others (the finished ones' files untouched) and ends with the table of an unstopped sweep."""
import json
import os
import signal
import subprocess
import sys
import time

from sweep_iotas import GRID


def test_an_interrupted_sweep_resumes(system, first_table, tmp_path):
    out = tmp_path / "sweep"
    command = [sys.executable, "-m", "iotad", "sweep", str(system), *GRID, "-o", str(out), "--plain", "-j", "1"]
    sweep = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not list(out.glob("runs/*.json")) and sweep.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        os.killpg(sweep.pid, signal.SIGINT)  # Ctrl-C, as a terminal sends it: to the sweep and its workers
        _, err = sweep.communicate(timeout=60)
    finally:
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
            sweep.wait()
    assert sweep.returncode == 130, err
    rows = [json.loads(path.read_text()) for path in out.glob("runs/*.json")]
    finished = {f"{row['run']}.mcap": (out / "runs" / f"{row['run']}.mcap").stat().st_mtime_ns
                for row in rows if row["status"] == "ok"}
    assert 1 <= len(finished) < 8, err
    assert "the same command again resumes" in err

    again = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert again.returncode == 0, again.stderr
    assert f"({len(finished)} done before;" in again.stdout
    assert (out / "results.csv").read_text() == first_table
    assert {name: (out / "runs" / name).stat().st_mtime_ns for name in finished} == finished
