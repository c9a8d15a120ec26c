"""The msgpack codec of typed channel values: the bytes a node publishes and the recorder stores.

`encode(type, value)` checks the value and packs `type.to_plain(value)`; `decode(type, payload)`
unpacks and rebuilds it with `type.from_plain` (ranges checked). Both raise `BadValue` for a
value that does not fit and `decode` raises `iotad.node_host.wire.WireError` for bytes that are not msgpack.
"""
from __future__ import annotations

from typing import Any

from iotad.node_host import wire
from iotad.kernel.types import Type


def encode(type: Type | None, value: Any) -> bytes:
    if type is None:
        return wire.encode(None)
    type.check(value)
    return wire.encode(type.to_plain(value))


def decode(type: Type | None, payload: bytes) -> Any:
    plain = wire.decode(payload)
    return plain if type is None else type.from_plain(plain)
