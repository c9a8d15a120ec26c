"""The lines of a host's run, numbered, so that the hub gets the ones a network cut kept from it.

An agent (iotad/launcher/hosts/agent.py) relays every line its run prints to the hub as it comes, and
a line relayed while the host is cut off reaches nobody: zenoh drops a publication with no route.
So each line is numbered within its run and the agent keeps the last `KEPT` of them
(`KeptLines`). The hub (iotad/launcher/hosts/fleet.py) notes the numbers it heard (`HeardLines`): a
number past the next one, the agent coming back, or the run's exit naming more lines than the
hub heard, is a gap, and the hub asks the agent for the lines after the last it heard
(`.../lines?after=N`) and prints them marked as late. Lines the agent no longer keeps are
counted, not lost silently.
"""
from __future__ import annotations

import threading
from collections import deque

KEPT = 10_000  # lines an agent keeps of its run: a long cut of a chatty run loses its oldest, counted


class KeptLines:
    """The agent's side: the run's lines, numbered from 1, the last `kept` of them kept."""

    def __init__(self, kept: int = KEPT):
        self._lines: deque[tuple[int, str]] = deque(maxlen=kept)
        self._count = 0
        self.run: int | None = None  # the run they are from (its launcher's pid)
        self._lock = threading.Lock()

    def start(self, run: int) -> None:
        """A new run: numbering starts again."""
        with self._lock:
            self._lines.clear()
            self._count, self.run = 0, run

    def add(self, line: str) -> int:
        """Keep `line`; its number."""
        with self._lock:
            self._count += 1
            self._lines.append((self._count, line))
            return self._count

    @property
    def count(self) -> int:
        return self._count

    def after(self, number: int, limit: int = 2000) -> dict:
        """The answer to `.../lines?after=N`: the run, up to `limit` lines numbered past `number`
        (oldest first), and the first number still kept."""
        with self._lock:
            lines = [[n, text] for n, text in self._lines if n > number][:limit]
            first = self._lines[0][0] if self._lines else self._count + 1
            return {"run": self.run, "first": first, "count": self._count, "lines": lines}


class HeardLines:
    """The hub's side, for one host: the lines of its run in their order. A live line past the
    next number is held, the caller asks the agent for the lines after the last printed, and the
    answer and the held lines are printed together in order (the answer's own marked late)."""

    def __init__(self):
        self.run = None
        self.next = 1           # the number of the next line to print
        self.held: dict[int, str] = {}
        self.asking = False     # a question is on its way: live lines are held until it is answered
        self.tail = False       # it asks for the run's last lines (its exit, or the agent back), not a gap
        self._lock = threading.Lock()

    def _new_run(self, run) -> None:
        self.run, self.next, self.held = run, 1, {}

    def live(self, run, number, text: str) -> tuple[list[tuple[str, bool]], bool]:
        """A line that came live: (the lines to print now as (text, late), whether to ask for
        the ones before it). A line without a number (an agent from before numbering) is printed."""
        if not isinstance(number, int):
            return [(text, False)], False
        with self._lock:
            if run != self.run:
                self._new_run(run)  # the host's part started again: its numbering too
            if number < self.next:
                return [], False  # printed already (from an answer)
            if number == self.next and not self.asking:
                self.next += 1
                return [(text, False)], False
            self.held[number] = text
            ask = not self.asking
            self.asking = True
            return [], ask

    def want_tail(self, run, count) -> bool:
        """The run's exit says it printed `count` lines (None: not known, as when its agent comes
        back after a cut): whether to ask for the ones not heard."""
        with self._lock:
            if run is not None and run != self.run:
                self._new_run(run)  # a run none of whose lines came live
            if self.asking or (isinstance(count, int) and count < self.next):
                return False
            self.asking = self.tail = True
            return True

    def after(self) -> int:
        """The number to ask `after=` for: the last line printed."""
        with self._lock:
            return self.next - 1

    def answered(self, answer: dict) -> tuple[list[tuple[str, bool]], int, bool]:
        """The agent's answer: (the lines to print as (text, late), how many it no longer kept,
        whether to ask again: more lines than one answer holds)."""
        with self._lock:
            if answer.get("run") != self.run:
                if self.run is not None or self.held:
                    return self._release(), 0, False  # another run's numbers
                self._new_run(answer.get("run"))  # none of its lines came live
            dropped = 0
            first = answer.get("first")
            if isinstance(first, int) and first > self.next:
                dropped, self.next = first - self.next, first
            # up to the last line held: the ones after it were printed since, and come live (a
            # question after the run's end, or after a cut with nothing live since, takes them all)
            upto = max(self.held) if self.held else None
            lines = {item[0]: (item[1], True) for item in answer.get("lines") or []
                     if isinstance(item, (list, tuple)) and len(item) == 2 and isinstance(item[0], int)
                     and isinstance(item[1], str) and item[0] >= self.next and (upto is None or item[0] < upto)}
            lines.update({n: (text, False) for n, text in self.held.items() if n >= self.next})
            out = []
            for number in sorted(lines):
                if number > self.next:
                    break  # a hole: the answer stopped at its limit, the rest comes from asking again
                out.append(lines[number])
                self.next = number + 1
            self.held = {n: t for n, t in self.held.items() if n >= self.next}
            if not out and self.held:  # the agent has not the lines before the held ones
                missing = min(self.held) - self.next
                return self._release(), dropped + missing, False
            count = answer.get("count")
            again = bool(out) and (bool(self.held) or (self.tail and isinstance(count, int) and count >= self.next))
            self.asking = again
            self.tail = self.tail and again
            return out, dropped, again

    def unanswered(self) -> tuple[list[tuple[str, bool]], int]:
        """No answer came: the held lines as they are, and how many before them were not heard."""
        with self._lock:
            missing = min(self.held) - self.next if self.held else 0
            return self._release(), missing

    def _release(self) -> list[tuple[str, bool]]:
        out = [(self.held[n], False) for n in sorted(self.held)]
        if self.held:
            self.next = max(self.held) + 1
        self.held, self.asking, self.tail = {}, False, False
        return out
