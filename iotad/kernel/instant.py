"""The instant the engine is executing, for code that asks the time without being passed it.

The kernel calls an action's functions with no time (`f(iota, index)`): time is the engine's.
ESPRIT's `now()` and a Python IOTA's `esprit_now()` read it here. The engine sets it before it
runs any of an IOTA's code (a firing, a delivered input, the first evaluation) and puts the one
before back when its public entry returns, so an engine run inside another's action leaves the
outer instant as it was, and code outside every run finds none.

An explicit cell rather than a look at the caller's stack frames: a compiled engine has no
Python frames to look at, and a cell costs one attribute store per firing. It is per thread:
a process may run an engine in each of several threads.
"""
from __future__ import annotations

import threading


class _Current(threading.local):
    instant: float | None = None  # the instant being executed; None: no engine is running here


current = _Current()
