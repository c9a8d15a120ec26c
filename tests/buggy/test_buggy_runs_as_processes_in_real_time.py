"""The same Buggy as six processes over zenoh in real time, on a CAN bus of a tier (what `make
demo` runs, shorter): it records, moves, and draws, and its nodes replay from the recording."""
import re
import subprocess
import sys

import pytest

from buggy_runs import ROOT, outputs


def test_a_short_real_time_run_records_buggy_moving(tmp_path):
    tiers = subprocess.run([sys.executable, "-m", "iotad.can.tiers"], capture_output=True, text=True).stdout
    if not re.search(r"^(vcan|udp_multicast)\s+available", tiers, re.M):
        pytest.skip(f"no CAN tier that runs processes at native speed here:\n{tiers}")
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "buggy" / "demo.py"), "--seconds", "10",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    recording = tmp_path / "buggy-demo.mcap"
    recorded = outputs(recording, "pose")
    assert {node for _, node, _, _ in recorded} == {"body"}
    poses = [v for *_, v in recorded]
    assert len(poses) >= 20  # 10 a second once the body is up
    assert len({(round(p["x"], 2), round(p["y"], 2)) for p in poses}) > 5
    moods = outputs(recording, "mood")
    assert moods and all(v["active"] in ("CONSCIOUS", "SUBCONSCIOUS") for *_, v in moods)
    assert (tmp_path / "buggy-demo.png").stat().st_size > 10_000
    assert "try next:" in done.stdout
    # a real-time recording replays at its recorded firing times: body (physics steps, then
    # sensors) and conscious (timers that count from their own firings) agree, value for value
    for node in ("body", "conscious"):
        replayed = subprocess.run([sys.executable, "-m", "iotad", "replay", str(recording), "--node", node],
                                  capture_output=True, text=True, timeout=120, cwd=ROOT)
        assert replayed.returncode == 0, replayed.stdout[-3000:] + replayed.stderr[-3000:]
        assert "replay agrees" in replayed.stdout and "each firing at its recorded time" in replayed.stdout
