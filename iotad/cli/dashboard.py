"""What `iotad top` shows, computed from what a running system publishes: liveliness tokens,
heartbeats, `@trace` bursts and channel messages. No zenoh here: `iotad top` feeds it samples,
and tests feed it the same samples by hand.

- nodes: alive or gone (its liveliness token), restarts (a token that comes back after going),
  heartbeat age, firings, input backlog, violations;
- channels: messages per second over the last `window` seconds and the p99 latency from the
  sender's send stamp (the wire attachment) to this tool's receipt;
- who holds the motors: a node whose trace has `schedule[i]` firings is a scheduler; its holder is
  the requester whose `schedule` fired last, until its `commit` (or another `schedule`); the
  requester's name comes from the scheduler's `@spec` (which output is bound to `req[i]`);
- the last violations, as they arrive.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

VIOLATIONS_KEPT = 8


@dataclass
class NodeRow:
    path: str
    host: str | None = None  # from its @spec answer: the system file's host, else the machine's name
    alive: bool = False
    restarts: int = 0
    seen_gone: bool = False
    beat_wall: float | None = None  # wall clock of the last heartbeat
    firings: int | None = None
    queue: int | None = None
    violations: int = 0


@dataclass
class ChannelRow:
    key: str
    arrivals: deque = field(default_factory=deque)     # wall clock of each message in the window
    latencies: deque = field(default_factory=deque)    # (wall clock, latency s)
    total: int = 0


@dataclass
class Holder:
    scheduler: str
    index: int | None = None
    since: float | None = None  # the scheduler's own time of the `schedule` firing
    names: dict[int, str] = field(default_factory=dict)

    @property
    def name(self) -> str:
        if self.index is None:
            return "free"
        return self.names.get(self.index, f"req[{self.index}]")


class Dashboard:
    def __init__(self, system: str | None = None, window: float = 5.0, clock=time.time):
        self.system, self.window, self.clock = system, window, clock
        self.nodes: dict[str, NodeRow] = {}
        self.channels: dict[str, ChannelRow] = {}
        self.holders: dict[str, Holder] = {}
        self.violations: deque = deque(maxlen=VIOLATIONS_KEPT)
        self.ignored = 0  # samples that could not be read (counted, never fatal)

    # ---------------------------------------------------------------- feeding
    def node(self, path: str) -> NodeRow:
        row = self.nodes.get(path)
        if row is None:
            row = self.nodes[path] = NodeRow(path)
        return row

    def alive(self, path: str, present: bool) -> None:
        row = self.node(path)
        if present and not row.alive and row.seen_gone:
            row.restarts += 1
        if not present and row.alive:
            row.seen_gone = True
        row.alive = present

    def heartbeat(self, path: str, value: Any) -> None:
        row = self.node(path)
        row.beat_wall = self.clock()
        if isinstance(value, dict):
            row.firings, row.queue = value.get("firings"), value.get("queue")
            restarts = value.get("restarts")  # the launcher's count, from before this tool began
            if isinstance(restarts, int) and not isinstance(restarts, bool) and restarts > row.restarts:
                row.restarts = restarts

    def spec(self, path: str, spec: dict) -> None:
        """A node's `@spec` answer: its host, and the requesters of a scheduler (req[i] <- node)."""
        if isinstance(spec.get("host"), str):
            self.node(path).host = spec["host"]
        names = {}
        for channel in spec.get("channels") or []:
            if channel.get("name") != "req" or channel.get("direction") != "input":
                continue
            for label, keys in (channel.get("bound") or {}).items():
                member = str(label).rpartition("/")[2]  # "req/0"; a plain "req" is member 0
                index = int(member) if member.isdigit() else 0
                if keys:  # iota/<system>/<node path>/<channel>: the sender
                    parts = str(keys[0]).split("/")
                    names[index] = "/".join(parts[2:-1]) or keys[0]
        if names:
            self._holder(path).names.update(names)

    def trace(self, path: str, events: list) -> None:
        for event in events:
            if not isinstance(event, dict):
                self.ignored += 1
                continue
            kind, action, index = event.get("kind"), event.get("action"), event.get("index")
            if kind == "violation":
                self.node(path).violations += 1
                value = event.get("value") if isinstance(event.get("value"), dict) else {}
                self.violations.append((self.clock(), path, action, value.get("violation", "?"),
                                        str(value.get("message", ""))[:120]))
            elif kind == "internal" and action == "schedule":
                holder = self._holder(path)
                holder.index, holder.since = index, event.get("t")
            elif kind == "internal" and action == "commit":
                holder = self.holders.get(path)
                if holder is not None and holder.index == index:
                    holder.index, holder.since = None, event.get("t")

    def message(self, key: str, send_ns: int | None) -> None:
        now = self.clock()
        row = self.channels.get(key)
        if row is None:
            row = self.channels[key] = ChannelRow(key)
        row.total += 1
        row.arrivals.append(now)
        if send_ns is not None:
            row.latencies.append((now, max(0.0, now - send_ns / 1e9)))
        self._trim(row, now)

    def _holder(self, path: str) -> Holder:
        holder = self.holders.get(path)
        if holder is None:
            holder = self.holders[path] = Holder(path)
        return holder

    def _trim(self, row: ChannelRow, now: float) -> None:
        edge = now - self.window
        while row.arrivals and row.arrivals[0] < edge:
            row.arrivals.popleft()
        while row.latencies and row.latencies[0][0] < edge:
            row.latencies.popleft()

    # ---------------------------------------------------------------- reading
    def rate(self, key: str) -> float:
        row = self.channels[key]
        self._trim(row, self.clock())
        return len(row.arrivals) / self.window

    def p99_ms(self, key: str) -> float | None:
        row = self.channels[key]
        self._trim(row, self.clock())
        if not row.latencies:
            return None
        ordered = sorted(latency for _, latency in row.latencies)
        return 1e3 * ordered[min(len(ordered) - 1, math.ceil(0.99 * len(ordered)) - 1)]

    def node_rows(self) -> list[tuple]:
        now = self.clock()
        rows = []
        for path in sorted(self.nodes):
            row = self.nodes[path]
            age = "-" if row.beat_wall is None else f"{now - row.beat_wall:.1f}s"
            rows.append((path, row.host or "?", "alive" if row.alive else "gone", str(row.restarts), age,
                         "-" if row.firings is None else str(row.firings),
                         "-" if row.queue is None else str(row.queue), str(row.violations)))
        return rows

    def channel_rows(self) -> list[tuple]:
        rows = []
        for key in sorted(self.channels):
            p99 = self.p99_ms(key)
            rows.append((key, f"{self.rate(key):.1f}", "-" if p99 is None else f"{p99:.2f}",
                         str(self.channels[key].total)))
        return rows

    def holder_lines(self) -> list[str]:
        lines = []
        for h in self.holders.values():
            line = f"{h.scheduler}: {h.name}" + ("" if h.since is None else f" (since t={h.since:.2f})")
            row = self.nodes.get(h.scheduler)
            if row is not None and row.seen_gone and not row.alive:
                line += ", last known: the scheduler is gone"  # a restarted one starts free
            lines.append(line)
        return lines

    def render(self) -> Any:
        """A rich renderable of the whole screen."""
        from rich.console import Group
        from rich.table import Table
        from rich.text import Text

        title = f"iotad top: {self.system or 'every system'}"
        nodes = Table(title=title, title_justify="left")
        for column in ("node", "host", "state", "restarts", "heartbeat", "firings", "queue", "violations"):
            nodes.add_column(column, justify="left" if column in ("node", "host") else "right")
        for row in self.node_rows():
            nodes.add_row(*row, style=None if row[2] == "alive" else "red")
        channels = Table(title="channels (last %gs)" % self.window, title_justify="left")
        for column in ("key", "msg/s", "p99 ms", "total"):
            channels.add_column(column, justify="left" if column == "key" else "right")
        for row in self.channel_rows():
            channels.add_row(*row)
        holders = self.holder_lines() or ["(no scheduler seen yet)"]
        parts = [nodes, Text("motors held by: " + "; ".join(holders), style="bold"), channels]
        if self.violations:
            parts.append(Text("violations:", style="bold red"))
            for wall, path, action, kind, message in self.violations:
                parts.append(Text(f"  {time.strftime('%H:%M:%S', time.localtime(wall))} {path}.{action}: "
                                  f"{kind}: {message}", style="red"))
        if self.ignored:
            parts.append(Text(f"{self.ignored} unreadable sample(s) ignored", style="dim"))
        return Group(*parts)
