"""A node's CAN port: its `can_tx` output events sent on a python-can bus, and every frame the
bus receives posted to the engine as a `can_rx` input event (docs/internals.md "CAN port").

The node's IOTA never sees python-can: it reads and writes `canFrame` values on two channels,
exactly as it does on the modelled bus of `iotad run --virtual`. So the same IOTA runs against a
real controller on can0, a simulated one on vcan0, or the bus model in virtual time. Frames are
received on a thread of their own (python-can blocks) and handed over undecoded-free: the engine
thread type-checks them like any other input, so a frame and a zenoh input are ordered alike.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from iotad.can.frame import Frame, FrameError
from iotad.host import wire
from iotad.host.host_clock import RawInput
from iotad.kernel.types import to_plain

CAN_TX, CAN_RX = "can_tx", "can_rx"


class CanPortError(Exception):
    """The bus named by the node's config cannot be opened; `str()` says why and what to try."""


class CanPort:
    def __init__(self, config: dict[str, Any], post: Callable[[RawInput], None]):
        self.config, self.post = config, post
        self.name = config["bus"]
        self.key = f"can/{self.name}"  # what an input trace event names as where it came from
        self.bus = None
        self.sent = self.received = self.send_errors = self.unusable = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def open(self) -> None:
        from iotad.can.bus import open_bus

        config = self.config
        try:
            self.bus = open_bus(config["interface"], config.get("channel"), bitrate=config.get("bitrate"),
                                **config.get("options", {}))
        except Exception as exc:  # noqa: BLE001 - python-can raises many kinds; the message is what matters
            raise CanPortError(f"CAN bus {self.name!r} ({config['interface']} {config.get('channel') or ''}): "
                               f"cannot open: {exc}") from None
        self._thread = threading.Thread(target=self._receive, name=f"can {self.name}", daemon=True)
        self._thread.start()

    def send(self, value: Any) -> str | None:
        """Put a `canFrame` value on the bus; the reason it could not, or None."""
        try:
            self.bus.send(Frame.from_value(value).to_can_message())
        except FrameError as exc:
            self.send_errors += 1
            return f"not a CAN frame: {exc}"
        except Exception as exc:  # noqa: BLE001 - a full transmit queue, a bus gone down
            self.send_errors += 1
            return f"CAN bus {self.name!r} refused a frame: {exc}"
        self.sent += 1
        return None

    def _receive(self) -> None:
        bus, post, stop = self.bus, self.post, self._stop
        while not stop.is_set():
            try:
                message = bus.recv(timeout=0.1)
            except Exception:  # noqa: BLE001 - the bus is shutting down under us
                if stop.is_set():
                    return
                continue
            if message is None:
                continue
            try:
                frame = Frame.from_can_message(message)
            except FrameError:
                self.unusable += 1  # error frames, CAN FD: not classic frames any IOTA could take
                continue
            self.received += 1
            post(RawInput(CAN_RX, None, wire.encode(to_plain(frame.to_value())), None, self.key))

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
        if self.bus is not None:
            bus, self.bus = self.bus, None
            try:
                bus.shutdown()
            except Exception:  # noqa: BLE001 - closing anyway
                pass
