"""ESPRIT diagnostics: `file:line:col: message`, then the source line and a caret under the column."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Diagnostic:
    filename: str
    line: int
    col: int
    message: str
    source_line: str = ""
    severity: str = "error"  # or "warning"

    def __str__(self) -> str:
        head = f"{self.filename}:{self.line}:{self.col}: "
        if self.severity == "warning":
            head += "warning: "
        text = head + self.message
        if self.source_line:
            shown = self.source_line.expandtabs(1).rstrip("\n")
            text += f"\n    {shown}\n    {' ' * max(self.col - 1, 0)}^"
        return text


class EspritError(Exception):
    """A specification that cannot be loaded. `str()` is the first diagnostic; `diagnostics`
    holds every error found (the static checker reports all it can, not just the first)."""

    def __init__(self, diagnostic: Diagnostic, more: list[Diagnostic] | None = None):
        super().__init__(str(diagnostic))
        self.diagnostic = diagnostic
        self.diagnostics = [diagnostic] + [d for d in (more or []) if d is not diagnostic]

    @property
    def line(self) -> int:
        return self.diagnostic.line

    @property
    def col(self) -> int:
        return self.diagnostic.col


class Source:
    """The text of one spec file, to turn positions into diagnostics."""

    def __init__(self, text: str, filename: str):
        # a byte-order mark (editors on Windows write one) says how the file is encoded; it is no
        # character of the spec, and an invisible one is the worst error to point a caret at
        text = text[1:] if text.startswith("\ufeff") else text
        self.text, self.filename = text, filename
        self.lines = text.split("\n")

    def diagnostic(self, pos: tuple[int, int] | None, message: str, severity: str = "error") -> Diagnostic:
        line, col = pos or self.end()
        if line < 1 or line > len(self.lines):
            line, col = self.end()
        return Diagnostic(self.filename, line, max(col, 1), message, self.lines[line - 1], severity)

    def end(self) -> tuple[int, int]:
        """Just after the last character that is not white space: where "end of file" points."""
        body = self.text.rstrip()
        line = body.count("\n") + 1
        return line, len(body) - (body.rfind("\n") + 1) + 1

    def error(self, pos: tuple[int, int] | None, message: str) -> EspritError:
        return EspritError(self.diagnostic(pos, message))
