"""Where an exception raised in an IOTA's own code came from: the file and line of its innermost
frame outside iotad itself, and the traceback as text, for violations and load errors."""
from __future__ import annotations

import traceback
from pathlib import Path

_IOTAD = str(Path(__file__).resolve().parent.parent) + "/"  # iotad's own frames are not the user's line


def fault_where(exc: BaseException) -> str | None:
    """`file:line` of the innermost frame of `exc`'s traceback outside iotad (the line of the
    node's own code that raised), or None when no frame is the node's (iotad itself refused)."""
    for frame in reversed(traceback.extract_tb(exc.__traceback__)):
        if not _ours(frame.filename):
            return f"{frame.filename}:{frame.lineno}"
    return None


def _ours(filename: str) -> bool:
    # "<esprit ...>": code generated from an ESPRIT spec, whose errors name the spec's own terms
    return filename.startswith("<") or str(Path(filename).resolve()).startswith(_IOTAD)


def fault_traceback(exc: BaseException) -> str:
    """The traceback of `exc` as Python prints it, without iotad's own frames at its top."""
    frames = traceback.extract_tb(exc.__traceback__)
    first = 0
    while first < len(frames) - 1 and _ours(frames[first].filename):
        first += 1
    lines = ["Traceback (most recent call last):\n", *traceback.format_list(frames[first:]),
             *traceback.format_exception_only(type(exc), exc)]
    return "".join(lines)


def fault_text(exc: BaseException) -> str:
    """`Type: message (at file:line)`: one line for a violation's message or a load error."""
    where = fault_where(exc)
    text = f"{type(exc).__name__}: {exc}"
    return f"{text} (at {where})" if where else text


class NodeViolation(Exception):
    """Raised by a node's own code (an action's `do` block, after its state changes) to record a
    violation it found itself: the engine records `{"violation": code, "message": str(self)}` on
    the action's channel, not a runtime_error, and the node goes on. Keyword `fields` (plain
    values: numbers, strings, lists of them) go into that record beside the message, so that a
    tool can read what the message says in words."""

    def __init__(self, code: str, message: str, /, **fields):
        super().__init__(message)
        self.code = code
        self.fields = fields
