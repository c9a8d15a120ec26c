"""A node's CAN port: its `can_tx` output events sent on a python-can bus, and every frame the
bus receives posted to the engine as a `can_rx` input event (docs/internals.md "CAN port").

The node's IOTA never sees python-can: it reads and writes `canFrame` values on two channels,
exactly as it does on the modelled bus of `iotad run --virtual`. So the same IOTA runs against a
real controller on can0, a simulated one on vcan0, or the bus model in virtual time. Frames are
received on a thread of their own (python-can blocks) and handed over as plain values (no wire
format carried them, so no msgpack round trip) and marked as built with canFrame's checks
(`CheckedPlain`), which the engine then does not repeat; the engine thread takes them in order
with the zenoh inputs.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from iotad.can.burst_types import CAN_FRAMES
from iotad.can.error_frames import describe_error_frame
from iotad.can.frame import CAN_FRAME, Frame, FrameError
from iotad.kernel.types import CheckedPlain
from iotad.node_host.host_clock import DecodedInput

CAN_TX, CAN_RX = "can_tx", "can_rx"
CAN_TX_BURST = "can_tx_burst"  # a node's frames of one instant as one output, sent one by one (iotad.can.burst_bus)
CAN_RX_BURST = "can_rx_burst"  # a node's input of the frames received together, in order (a list of canFrame)
BURST_MAX = 64  # frames at most in one can_rx_burst (what a waiting socket holds is taken in these)
TX_BURSTS = "tx_bursts"  # the param of a station that can send either way; its host sets it true
KEY_PREFIX = "can/"  # an input trace event's `key` for a frame from the bus: can/<bus> (no zenoh key)
# the bus's receive built each frame with Frame's checks, which are canFrame's: the engine need not
# check it again (iotad.kernel.types.CheckedPlain)
CHECKED_FRAME, CHECKED_FRAMES = CheckedPlain(CAN_FRAME), CheckedPlain(CAN_FRAMES)
RETRY = 0.1  # s between receive attempts on a bus that fails (an interface gone down): no busy loop

# What the reader thread saw that no IOTA can take, as the violations the host records (on can_rx):
ERROR_FRAME = "can_error_frame"        # the controller's report of a bus problem (bus off, no ACK...)
UNUSABLE = "can_frame_unusable"        # a CAN FD frame: an IOTA takes classic frames only
RECEIVE_FAILED = "can_receive_failed"  # the bus raised on receive


class CanPortError(Exception):
    """The bus named by the node's config cannot be opened; `str()` says why and what to try."""


class CanPort:
    """`post` takes each frame received (a `DecodedInput` for the engine thread); `now` is the
    engine's clock, which stamps the problems `take_problems` hands over."""

    def __init__(self, config: dict[str, Any], post: Callable[[DecodedInput], None],
                 now: Callable[[], float] = lambda: 0.0, burst: bool = False):
        self.config, self.post, self.now = config, post, now
        self.burst = burst  # the node takes the frames received together as one `can_rx_burst` input
        self.name = config["bus"]
        self.key = f"{KEY_PREFIX}{self.name}"  # what an input trace event names as where it came from
        self.bus = None
        self.sent = self.received = self.send_errors = self.unusable = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        # violation -> [count, first t, last t, what the first one said]: counted by the reader
        # thread, handed to the engine thread by `take_problems` (a flood is one record per period)
        self._problems: dict[str, list] = {}
        self._problems_lock = threading.Lock()

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
        problems = self.send_all((value,))
        return problems[0] if problems else None

    def send_all(self, values) -> list[str]:
        """Put an instant's `canFrame` values on the bus in their order (a `can_tx_burst`); the
        reasons of those that could not go, in order (the others still go)."""
        problems = []
        send = self.bus.send_plain
        for value in values:
            try:
                send(value)
            except FrameError as exc:
                self.send_errors += 1
                problems.append(f"not a CAN frame: {exc}")
                continue
            except Exception as exc:  # noqa: BLE001 - a full transmit queue, a bus gone down
                self.send_errors += 1
                problems.append(f"CAN bus {self.name!r} refused a frame: {exc}")
                continue
            self.sent += 1
        return problems

    def _receive(self) -> None:
        bus, post, stop, key = self.bus, self.post, self._stop, self.key
        # what the bus already holds goes with the first frame, in one input (`can_rx_burst`):
        # a node that fell behind catches up in one step, not one per frame
        limit = BURST_MAX if self.burst else 1
        while not stop.is_set():
            try:
                frames, others = bus.recv_plain(0.1, limit)
            except Exception as exc:  # noqa: BLE001 - python-can raises many kinds
                if stop.is_set():
                    return  # the bus is shutting down under us
                self._problem(RECEIVE_FAILED, f"{type(exc).__name__}: {exc}")
                stop.wait(RETRY)
                continue
            for other in others:
                self._unusable(other)
            self.received += len(frames)
            if len(frames) == 1:
                post(DecodedInput(CAN_RX, None, frames[0], key, CHECKED_FRAME))
            elif frames:
                post(DecodedInput(CAN_RX_BURST, None, frames, key, CHECKED_FRAMES))

    def _unusable(self, other: Any) -> None:
        """Record what came on the bus that no IOTA can take: an error frame (the controller's
        report of a bus problem), a CAN FD frame, a datagram that is no frame (FrameError)."""
        if getattr(other, "is_error_frame", False):
            self._problem(ERROR_FRAME, describe_error_frame(other.arbitration_id, other.data))
            return
        self.unusable += 1
        if isinstance(other, FrameError):
            self._problem(UNUSABLE, str(other))
        else:
            self._problem(UNUSABLE, f"CAN FD frame 0x{other.arbitration_id:X} with {other.dlc} bytes is not "
                                    f"classic CAN")

    def _problem(self, violation: str, said: str) -> None:
        t = self.now()
        with self._problems_lock:
            entry = self._problems.get(violation)
            if entry is None:
                self._problems[violation] = [1, t, t, said]
            else:
                entry[0] += 1
                entry[2] = t

    def take_problems(self) -> list[tuple[str, str, int]]:
        """(violation, message, count) of each kind of problem the reader thread saw since the
        last call: error frames, unusable frames, failed receives (engine thread)."""
        with self._problems_lock:
            problems, self._problems = self._problems, {}
        found = []
        for violation, (count, first, last, said) in problems.items():
            what = {ERROR_FRAME: f"{count} error frame(s)", UNUSABLE: f"{count} frame(s) no IOTA can take",
                    RECEIVE_FAILED: f"{count} failed receive(s), retried every {RETRY:g} s"}[violation]
            found.append((violation, f"CAN bus {self.name!r}: {what} between t={first:.6f} and t={last:.6f}; "
                                     f"the first: {said}", count))
        return found

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
