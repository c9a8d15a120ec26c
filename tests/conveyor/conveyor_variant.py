"""examples/conveyor.toml, varied for tests: absolute paths (the copy lives in a temporary folder),
fewer objects, another CAN bus; and how to read a conveyor recording's channels."""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "conveyor.toml"
FOLDER = ROOT / "examples" / "conveyor"
IOTAD = str(Path(sys.executable).with_name("iotad"))  # the venv running the tests, also in a worktree

if str(FOLDER) not in sys.path:  # the example's modules import their neighbours by name
    sys.path.insert(0, str(FOLDER))


def system_variant(folder: Path, *, cube_count: int = 2, cube_interval: float = 6.0,
                   bus: tuple[str, str] | None = None) -> Path:
    text = EXAMPLE.read_text()
    text = text.replace('python = "conveyor/', f'python = "{FOLDER}/').replace('spec = "conveyor/', f'spec = "{FOLDER}/') \
        .replace('metrics = "conveyor/', f'metrics = "{FOLDER}/')
    text, n = re.subn(r"cube_count = \d+, cube_interval = [\d.]+",
                      f"cube_count = {cube_count}, cube_interval = {cube_interval}", text)
    assert n == 1, "the example's world_options changed: update tests/conveyor/conveyor_variant.py"
    if bus is not None:
        interface, channel = bus
        text, n = re.subn(r'interface = "[^"]*"[^\n]*\n(channel = "[^"]*"\n)?',
                          f'interface = "{interface}"\nchannel = "{channel}"\n', text)
        assert n == 1
    path = folder / "conveyor.toml"
    path.write_text(text)
    return path
