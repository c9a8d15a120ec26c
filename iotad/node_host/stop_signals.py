"""Stopping on signals with no lock taken in a signal handler: `StopSignals` (SIGINT, SIGTERM... as
a stop the main thread waits on, woken at once) and `Flag` (a flag a handler may set).

A Python signal handler runs in the main thread between two bytecodes, possibly while that
thread holds a lock, and a handler that takes the same lock waits for ever: `threading.Event.set()`
in a handler, landing while the main thread is inside that Event's `wait()` (which holds the
Event's lock around its waiting), or `queue.Queue.put()` while it is inside the queue's `get()`.
A recorder whose launcher was killed hung so, an orphan with its file never finished, about once
in thirty stops under load. Here a handler only appends to a list (atomic, lock-free), and
`StopSignals.wait` sleeps in select() on the signal wake-up fd, so that a signal ends it at once.
"""
from __future__ import annotations

import os
import select
import signal
import time
from typing import Iterable


class Flag:
    """A flag that a signal handler may set (`threading.Event` may deadlock there: see above)."""

    POLL = 0.02  # s between looks of `wait`

    def __init__(self) -> None:
        self._set: list[bool] = []

    def set(self) -> None:
        self._set.append(True)

    def is_set(self) -> bool:
        return bool(self._set)

    def wait(self, timeout: float) -> bool:
        """Whether it is set, after waiting at most `timeout` s for it (polled)."""
        deadline = time.monotonic() + timeout
        while not self._set and (left := deadline - time.monotonic()) > 0:
            time.sleep(min(self.POLL, left))
        return bool(self._set)


class StopSignals:
    """The `signals` received so far (`received`, in order); installs their handlers and the
    process's signal wake-up fd. Main thread only (as `signal.signal` is); `close()` puts the
    previous wake-up fd back."""

    def __init__(self, signals: Iterable[int] = (signal.SIGINT, signal.SIGTERM)):
        self.received: list[int] = []
        self._read, write = os.pipe()
        os.set_blocking(self._read, False)
        os.set_blocking(write, False)
        self._write = write
        self._previous_fd = signal.set_wakeup_fd(write, warn_on_full_buffer=False)
        for signum in signals:
            signal.signal(signum, self._on_signal)

    def _on_signal(self, signum: int, frame) -> None:
        self.received.append(signum)  # and nothing else: see the module's docstring

    def is_set(self) -> bool:
        return bool(self.received)

    def wait(self, timeout: float | None = None) -> bool:
        """Whether a stop signal came, after waiting at most `timeout` s for one (None: no limit)."""
        if not self.received:
            try:
                select.select([self._read], [], [], timeout)  # the C handler writes to the pipe at once
                os.read(self._read, 512)
            except (BlockingIOError, InterruptedError, OSError, ValueError):
                pass
        return bool(self.received)

    def close(self) -> None:
        """Hand the wake-up fd back (the handlers stay: a late signal is still only noted)."""
        try:
            signal.set_wakeup_fd(self._previous_fd)
        except ValueError:  # not the main thread
            pass
        for fd in (self._read, self._write):
            try:
                os.close(fd)
            except OSError:
                pass


__all__ = ["Flag", "StopSignals"]
