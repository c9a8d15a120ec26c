"""JSON Schemas of the registered message types, as the recorder stores them in MCAP.

`python -m channels.schema_gen` rewrites channels/schemas/*.json (committed, so that tools in other
languages can read them); `tests/test_channels.py` fails when they are out of date.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas"
DIALECT = "https://json-schema.org/draft/2020-12/schema"


def schema(name: str) -> dict:
    from . import lookup

    type = lookup(name)
    return {"$schema": DIALECT, **type.json_schema()}


def schema_json(name: str) -> str:
    """The schema of message type `name` as stable JSON text (sorted keys, one trailing newline)."""
    return json.dumps(schema(name), indent=2, sort_keys=True) + "\n"


def expected_files() -> dict[str, str]:
    from . import REGISTRY

    return {f"{name}.json": schema_json(name) for name in sorted(REGISTRY)}


def write_schemas(folder: Path = SCHEMA_DIR) -> list[Path]:
    """Write one file per registered type and remove files of types no longer registered."""
    folder.mkdir(parents=True, exist_ok=True)
    wanted = expected_files()
    for stale in folder.glob("*.json"):
        if stale.name not in wanted:
            stale.unlink()
    written = []
    for filename, text in wanted.items():
        path = folder / filename
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
        written.append(path)
    return written


def main() -> int:
    for path in write_schemas():
        print(path.relative_to(SCHEMA_DIR.parent.parent), file=sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
