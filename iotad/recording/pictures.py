"""The pictures `iotad plot` draws of a robot's run instead of the scheduler's timeline: what a
picture must offer (`Picture`), and where they are found (entry-point group `iotad.pictures`).

A picture is a module (or any object) with `matches(recording)`, true when the recording is of
its robot, and `plot(recording, output, title)`, which writes the image and returns its path.
A package registers one in its pyproject.toml, e.g.

    [project.entry-points."iotad.pictures"]
    buggy = "sim.worlds.buggy_plot"

so the library draws the paper's robots without knowing them (they live beside their worlds).
"""
from __future__ import annotations

from importlib.metadata import entry_points
from pathlib import Path
from typing import Protocol, runtime_checkable

from iotad.recording.mcap_reader import Recording

GROUP = "iotad.pictures"


@runtime_checkable
class Picture(Protocol):
    def matches(self, recording: Recording) -> bool:
        """Whether `recording` is of this picture's robot."""

    def plot(self, recording: Recording, output: str | Path, title: str | None = None) -> Path:
        """Draw it to `output` (its format follows the extension); the path written."""


def pictures() -> tuple[list[tuple[str, Picture]], list[str]]:
    """The registered pictures in name order, and why any registered one could not be used (one
    line each: a module that fails to import, or an object without `matches` and `plot`)."""
    found: list[tuple[str, Picture]] = []
    problems: list[str] = []
    for entry in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        try:
            picture = entry.load()
        except Exception as exc:  # noqa: BLE001 - a broken plug-in must not stop the other pictures
            problems.append(f"picture {entry.name!r} ({entry.value}) does not load: {type(exc).__name__}: {exc}")
            continue
        if not isinstance(picture, Picture):
            problems.append(f"picture {entry.name!r} ({entry.value}) has no matches() and plot()")
            continue
        found.append((entry.name, picture))
    return found, problems
