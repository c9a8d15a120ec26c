"""Which engine is executing an IOTA's code in this thread, for code that asks the time without
being passed it.

The kernel calls an action's functions with no time (`f(iota, index)`): time is the engine's.
ESPRIT's `now()` and a Python IOTA's `esprit_now()` read `running.engine.executing`, the instant
that engine is executing. An engine makes itself `running.engine` at each public entry (`run`,
`start`, `fire_due`, `deliver`, `fire_instance`) and puts the one before back when it returns,
so an engine run inside another's action leaves the outer one in place, and code outside every
run finds none. Inside, it only updates its own `executing` (a plain attribute store) as time
moves: the per-firing cost stays off the thread-local.

An explicit reference rather than a look at the caller's stack frames: a compiled engine has no
Python frames to look at, and reading a frame's locals builds a dict. It is per thread: a
process may run an engine in each of several threads.
"""
from __future__ import annotations

import threading
from typing import Any


class _Running(threading.local):
    engine: Any = None  # the engine executing an IOTA's code in this thread; None: none


running = _Running()
