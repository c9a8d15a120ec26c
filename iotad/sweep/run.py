"""One run of a sweep, in whatever process runs it (a local pool's worker, a Ray task): the
system with the run's parameter values, run as `iotad run --virtual --seed S --until T -o FILE`
runs it, then measured by the system's metrics hook. Whatever goes wrong (an exception, a time
out, a run cut short) is the run's failed row, never the sweep's end."""
from __future__ import annotations

import contextlib
import math
import os
import signal
import sys
import time
import traceback
from pathlib import Path
from typing import Any


class RunTimedOut(BaseException):
    """The run took longer than the sweep's --timeout (a BaseException: a node's `except
    Exception` must not swallow it)."""


def run_one(task: dict) -> dict:
    """Run `task` ({"run", "system", "values", "seed", "seed_param", "until", "timeout", "metrics",
    "recording", "log"}), recording to `task["recording"]` and its printed output to `task["log"]`. Returns the
    run's row: its status ("ok" or "failed"), error, metrics and wall seconds."""
    row: dict[str, Any] = {"run": task["run"], "status": "failed", "error": "", "metrics": {}}
    started = time.perf_counter()
    Path(task["log"]).parent.mkdir(parents=True, exist_ok=True)
    try:
        with _output_to(task["log"]):
            system = _checked(task["system"])  # once per worker, before the run's clock starts
            with _time_limit(task.get("timeout")):
                code = _run_virtual(task, system)
                row["metrics"] = measure(task, code)
        row["status"] = "ok"
    except RunTimedOut:
        row["error"] = f"timed out after {task['timeout']:g} s of wall time"
    except BaseException as exc:  # noqa: BLE001 - one run's failure, whatever it is, is its row
        if isinstance(exc, KeyboardInterrupt):
            row["error"] = "interrupted"
        else:
            row["error"] = _one_line(exc)
            with contextlib.suppress(OSError), open(task["log"], "a", encoding="utf-8") as log:
                traceback.print_exc(file=log)
    row["wall_s"] = round(time.perf_counter() - started, 3)
    return row


_SYSTEMS: dict = {}  # system file -> the system as checked: once per worker, not once per run


def _checked(path: str):
    """The system file checked as `iotad run` checks it, the first time this process runs it."""
    from iotad.sweep.plan import load_checked

    if path not in _SYSTEMS:
        _SYSTEMS[path] = load_checked(path)
    return _SYSTEMS[path]


def _run_virtual(task: dict, checked) -> int:
    from iotad.sweep.plan import apply
    from iotad.virtual.virtual_run import VirtualOptions, run_virtual

    values, seed = task["values"], task["seed"]
    if task.get("seed_param"):  # the seed is a node's (a world's), and the policy eager
        values, seed = {**values, task["seed_param"]: seed}, None
    system = apply(checked, values)
    options = VirtualOptions(until=task["until"], seed=seed, record_to=task["recording"], force=True, plain=True,
                             policy=task.get("policy"))
    # every core already runs a run: the recording is written in this process, not a second one
    return run_virtual(system, options, second_process=False)


def measure(task: dict, code: int) -> dict[str, Any]:
    """The run's metrics by the hook, once the recording shows a whole run."""
    from iotad.kernel.python_loader import load_object
    from iotad.recording.mcap_reader import read_recording

    recording = read_recording(task["recording"])
    if recording.run_error:
        raise RuntimeError(f"the run broke off: {recording.run_error}")
    end = (recording.run_end or 0.0) * recording.time_unit
    if code != 0 or end < task["until"] * (1 - 1e-9):  # a Ctrl-C stops a run early, cleanly
        raise RuntimeError(f"the run ended at t = {end:g} s of {task['until']:g} (exit status {code})")
    if task.get("goals"):  # iotad stress: the hook's metrics and the run's violations, as goals read them
        from iotad.recording.run_metrics import run_metrics
        return run_metrics(recording, task.get("metrics"))
    if not task.get("metrics"):
        return {}
    hook = load_object(task["metrics"])
    values = hook(recording)
    if not isinstance(values, dict):
        raise TypeError(f"metrics hook {task['metrics']} returned {type(values).__name__}, not a dict")
    out = {}
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            value = str(value) if not isinstance(value, bool) else int(value)
        elif isinstance(value, float) and not math.isfinite(value):
            value = str(value)
        out[str(name)] = value
    return out


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    name = type(exc).__name__
    return text if name in ("SweepError", "VirtualRunError", "RuntimeError") else f"{name}: {text}"


@contextlib.contextmanager
def _output_to(log: str):
    """Everything the run prints, Python's and a C library's (PyBullet's banner), into its log:
    file descriptors 1 and 2 point there while it runs."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with open(log, "w", encoding="utf-8") as handle:
        os.dup2(handle.fileno(), 1)
        os.dup2(handle.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)


@contextlib.contextmanager
def _time_limit(seconds: float | None):
    """Raise RunTimedOut in this thread after `seconds` of wall time (a timer signal: the run is
    interrupted between two Python bytecodes, wherever it is). Outside the main thread, no limit."""
    if not seconds:
        yield
        return

    def expired(signum, frame):
        raise RunTimedOut()

    try:
        previous = signal.signal(signal.SIGALRM, expired)
    except ValueError:  # not the main thread
        yield
        return
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
