"""Buggy runs shared by the Buggy tests: the example system files in virtual time, recorded, and
the recorded outputs as plain lists."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
IOTAD = str(Path(sys.executable).parent / "iotad")


def run_virtual(system: str, seconds: float, output: Path, *more: str) -> Path:
    done = subprocess.run([IOTAD, "run", str(ROOT / "examples" / system), "--virtual", "--until", str(seconds),
                           "-o", str(output), *more], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert ", 0 violations" in done.stdout, done.stdout
    return output


def outputs(path: Path, channel: str | None = None) -> list[tuple[float, str, str, object]]:
    """(t, node, channel, value) of every recorded output, in order."""
    return [(float(e["t"]), e["node"], e["action"], e.get("value")) for e in read_recording(str(path)).trace()
            if e.get("kind") == "output" and (channel is None or e["action"] == channel)]
