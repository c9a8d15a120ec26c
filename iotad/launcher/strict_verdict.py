"""What ends a strict run (`iotad run --strict`, `[system] strict = true`) non-zero: its
violations, a node's exception among them, and nodes that never went live, each said in a line."""
from __future__ import annotations


def strict_failures(violations: int, never_live: list[str]) -> list[str]:
    """The reasons a strict run fails, one line each (none: it passes)."""
    lines = []
    if violations:
        lines.append(f"{violations} violation(s) (listed above): the run's exit status is 1")
    for name in never_live:
        lines.append(f"node {name} never went live: the run's exit status is 1")
    return lines
