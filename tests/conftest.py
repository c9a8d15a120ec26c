"""Shared test set-up for every folder: the examples folder and this folder's helper modules
(launcher_helpers, node_harness, recorded_systems, system_iotas) are importable."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT / "examples", ROOT / "tests"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
