"""docs/design.md lists the runtime's modules one line each, by folder: a newcomer reads that
list to find where a thing lives, so a module missing from it is a module they will not find."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ["iotad/kernel", "iotad/esprit", "iotad/can", "iotad/ros2", "iotad/machine", "iotad/node_host", "iotad/launcher",
           "iotad/launcher/system", "iotad/launcher/access", "iotad/launcher/hosts", "iotad/launcher/run", "iotad/recording",
           "iotad/virtual", "iotad/sweep", "iotad/scaffold",
           "iotad/cli", "channels"]


def listed(folder: str) -> set[str]:
    text = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")
    start = text.index(f"**`{folder}/`**")
    end = text.find("\n**`", start + 1)
    return set(re.findall(r"^- `([\w.]+\.py)`", text[start:end if end > 0 else None], re.MULTILINE))


def test_every_module_of_the_runtime_has_its_line():
    missing = {folder: sorted(path.name for path in (ROOT / folder).glob("*.py")
                              if path.name != "__init__.py" and path.name not in listed(folder))
               for folder in FOLDERS}
    assert {folder: names for folder, names in missing.items() if names} == {}


def test_every_listed_module_exists():
    gone = {folder: sorted(name for name in listed(folder) if not (ROOT / folder / name).exists()) for folder in FOLDERS}
    assert {folder: names for folder, names in gone.items() if names} == {}
