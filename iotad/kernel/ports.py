"""Ports: one concrete channel of a node, "node.channel" or "node.channel[k]", parsed in one place.

Every part of iotad that names a channel in text reads it here: the composition of IOTAs
(`kernel/compose.py`, where a composite's own channel has no node: "channel[k]"), the system
file (`launcher/system/declaration.py`), and what reads a recorded system (delivery check, plots).
A node is an instance path (`arm/wrist`): chunks without spaces, dots or brackets.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

_PORT = re.compile(r"^\s*(?:(?P<node>[^\s\[\].]+)\.)?(?P<channel>[A-Za-z_]\w*)(?:\[(?P<index>\d+)\])?\s*$")


class PortSyntaxError(ValueError):
    """Text that is not "node.channel" or "node.channel[k]"."""


@dataclass(frozen=True)
class Port:
    """One concrete channel: node path, channel, index (None for a plain channel, or a whole family)."""

    node: str
    channel: str
    index: int | None = None

    def __str__(self) -> str:
        head = f"{self.node}." if self.node else ""
        return f"{head}{self.channel}" + ("" if self.index is None else f"[{self.index}]")

    @classmethod
    def parse(cls, text: object, *, node_optional: bool = False) -> Port:
        """The port `text` names; raises PortSyntaxError. With `node_optional`, "channel[k]"
        (a composite's own channel) parses too, with node ""."""
        match = _PORT.match(text) if isinstance(text, str) else None
        if match is None or (match["node"] is None and not node_optional):
            raise PortSyntaxError(f"{text!r} is not \"node.channel\" or \"node.channel[k]\"")
        index = match["index"]
        return cls(match["node"] or "", match["channel"], None if index is None else int(index))

    @classmethod
    def parsed(cls, text: object) -> Port | None:
        """The port `text` names, or None where it names none (a damaged or foreign file)."""
        try:
            return cls.parse(text)
        except PortSyntaxError:
            return None

    def member(self, index: int | None) -> Port:
        """The same channel with another index."""
        return Port(self.node, self.channel, index)
