"""The violations a run's summary shows: each distinct line once, with its count and the indices.

A family's members often miss the same deadline at the same instant (six axes of one arm); the
summary then says so in one line, `... x6 (i=0..5)`, instead of the same line six times and
no room left for a different one."""
from __future__ import annotations

from dataclasses import dataclass, field

LIMIT = 5  # distinct lines kept: the summary is a glance, the recording holds every violation


@dataclass
class _Group:
    count: int = 0
    indices: set[int] = field(default_factory=set)


class ViolationExamples:
    """The first `limit` distinct violation lines, each with how often it came and at which
    indices. A line already kept is counted however many came after it."""

    def __init__(self, limit: int = LIMIT):
        self.limit = limit
        self._groups: dict[str, _Group] = {}
        self.unshown = 0  # violations whose line came after `limit` others: counted, not shown

    def add(self, line: str, index: object = None) -> None:
        group = self._groups.get(line)
        if group is None:
            if len(self._groups) >= self.limit:
                self.unshown += 1
                return
            group = self._groups[line] = _Group()
        group.count += 1
        if isinstance(index, int) and not isinstance(index, bool):
            group.indices.add(index)

    def __len__(self) -> int:
        return len(self._groups)

    def lines(self) -> list[str]:
        return [line + _repeats(group) for line, group in self._groups.items()]

    def more(self, recording: str | None) -> str | None:
        """The line that says how many violations `lines()` leaves out, and where they are; None
        when it shows them all."""
        if not self.unshown:
            return None
        where = (f"'iotad info {recording} --violations N' lists them" if recording
                 else "a recording (-o FILE) would hold them")
        return f"... and {self.unshown} more, not shown here: {where}"


def _repeats(group: _Group) -> str:
    if group.count == 1:
        return ""
    return f" x{group.count}" + (f" (i={index_ranges(group.indices)})" if group.indices else "")


def index_ranges(indices: set[int]) -> str:
    """`0..5` for 0-5, `0,1,4..7` for a gappy set: runs of three or more as a range."""
    ordered, parts, start = sorted(indices), [], 0
    for i in range(1, len(ordered) + 1):
        if i == len(ordered) or ordered[i] != ordered[i - 1] + 1:
            run = ordered[start:i]
            parts.append(f"{run[0]}..{run[-1]}" if len(run) >= 3 else ",".join(map(str, run)))
            start = i
    return ",".join(parts)
