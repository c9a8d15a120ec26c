"""What `iotad run` shows: a live status table on a terminal, plain event lines elsewhere
(a pipe, a log file, CI), so that its output is as useful in a log as on a screen."""
from __future__ import annotations

import sys
import time
from typing import Any

COLUMNS = ("node", "host", "pid", "state", "restarts", "uptime", "heartbeat")
_STATE_STYLE = {"running": "green", "starting": "yellow", "waiting": "dim", "backoff": "yellow",
                "lost": "red", "stopping": "yellow", "stopped": "dim", "exited": "dim", "failed": "bold red",
                "down": "bold red"}


class StatusView:
    def __init__(self, console: Any = None, live: bool | None = None, title: str = "iotad"):
        from rich.console import Console

        self.console = console or Console(file=sys.stdout, highlight=False)
        # rich ends the program when its reader leaves (`iotad run ... | head`): here the system
        # runs on and is recorded; only its lines stop
        self.console.on_broken_pipe = self._mute
        self.live_enabled = self.console.is_terminal if live is None else live
        self.title = title
        self._live = None
        self._rows: list[tuple] = []
        self._t0 = time.monotonic()
        self._started = False

    def start(self) -> None:
        self._started = True
        if self.live_enabled and self._live is None:
            from rich.live import Live
            self._live = Live(self._table(), console=self.console, refresh_per_second=4, transient=False)
            self._live.start()

    def line(self, text: str) -> None:
        stamp = f"[{time.monotonic() - self._t0:7.2f}]"
        try:
            if self._live is not None:
                self._live.console.print(f"{stamp} {text}", markup=False, highlight=False)
            else:
                self.console.print(f"{stamp} {text}", markup=False, highlight=False, soft_wrap=True)
        except (BrokenPipeError, ValueError):  # the reader left (`| head`), or stdout was closed
            self._mute()

    def _mute(self) -> None:
        """Nobody reads our output any more: the run goes on, its record is the recording."""
        import os

        self._live = None
        self.live_enabled = False
        self.console.quiet = True
        try:  # what else prints (the summary) writes to nothing too, rather than failing
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
        except (AttributeError, OSError, ValueError):
            pass

    def update(self, rows: list[tuple]) -> None:
        self._rows = rows
        if self._live is not None:
            self._live.update(self._table())

    def stop(self) -> None:
        try:
            self._stop()
        except (BrokenPipeError, ValueError):
            self._mute()

    def _stop(self) -> None:
        if self._live is not None:
            self._live.update(self._table())
            self._live.stop()
            self._live = None
        elif self._started:
            # A final snapshot, since no table was on screen; dashes (nothing to say) left out.
            for row in self._rows:
                self.console.print("  " + "  ".join(f"{c}={v}" for c, v in zip(COLUMNS, row) if v not in ("", "-")),
                                   markup=False, highlight=False, soft_wrap=True)

    def _table(self) -> Any:
        from rich.table import Table
        from rich.text import Text

        table = Table(title=self.title, title_justify="left", expand=False)
        hosts = any(row[1] for row in self._rows)
        for column in COLUMNS:
            if column == "host" and not hosts:
                continue
            table.add_column(column, justify="right" if column in ("pid", "restarts", "uptime", "heartbeat") else "left")
        for row in self._rows:
            cells = [c for i, c in enumerate(row) if hosts or i != 1]
            state = row[3]
            style = _STATE_STYLE.get(state.split(" ")[0], "")
            cells[2 if not hosts else 3] = Text(state, style=style)
            table.add_row(*cells)
        return table
