"""Where a sweep's runs execute: a pool of local worker processes (spawned, never forked; one
per core by default), or Ray tasks on a Ray cluster whose recordings come back to the sweep's
folder. Both hand each finished run's row to `done(task, row)` as it comes; the order of
completion does not matter, since every run is deterministic for its seed."""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import tempfile
import threading
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Callable

from iotad.sweep import SweepError
from iotad.sweep.run import run_one

Done = Callable[[dict, dict], None]


def _worker_start() -> None:
    """A pool worker leaves Ctrl-C to its run (which stops cleanly at the first) and to the
    parent, which stops the sweep: idle, it ignores it, with no traceback. It dies with the
    sweep (a sweep killed outright must leave no worker running on), where Linux allows."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError, AttributeError):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG: when the sweep's process ends
        if os.getppid() == 1:  # the sweep died before the line above: do not run as an orphan
            os._exit(1)


def _died(task: dict, why: str) -> dict:
    return {"run": task["run"], "status": "failed", "error": why, "metrics": {}, "wall_s": 0.0}


def run_local(tasks: list[dict], jobs: int, done: Done) -> None:
    """Run `tasks` on `jobs` local worker processes. A worker that dies (a crash in C code, the
    memory killer) breaks the pool and every run in it: those runs are run again one at a time,
    so that only the run that kills its worker becomes a failed row."""
    lost = _pool(tasks, jobs, done)
    while lost:  # one at a time: a broken pool now names its run
        task, *lost = lost
        if _pool([task], 1, done):
            done(task, _died(task, "its worker process died (a crash outside Python, or killed)"))


def _pool(tasks: list[dict], jobs: int, done: Done) -> list[dict]:
    """The tasks lost to a broken pool (none when every run came back)."""
    context = multiprocessing.get_context("spawn")
    lost: list[dict] = []
    pool = ProcessPoolExecutor(max_workers=max(1, min(jobs, len(tasks))), mp_context=context,
                               initializer=_worker_start)
    # Ctrl-C noted, not raised wherever it lands: raised inside `wait`, whose futures' locks it
    # holds, it once left one released twice ("RuntimeError: release unlocked lock" instead of
    # the sweep's clean stop); the loop raises it itself between two waits
    interrupted = threading.Event()
    previous = (signal.signal(signal.SIGINT, lambda signum, frame: interrupted.set())
                if threading.current_thread() is threading.main_thread() else None)

    def restore() -> None:
        nonlocal previous
        if previous is not None:
            signal.signal(signal.SIGINT, previous)  # a second Ctrl-C during the stop: as before
            previous = None

    try:
        pending = {pool.submit(run_one, task): task for task in tasks}
        while pending:
            if interrupted.is_set():
                raise KeyboardInterrupt
            finished, _ = wait(pending, timeout=0.1, return_when=FIRST_COMPLETED)
            for future in finished:
                task = pending.pop(future)
                try:
                    row = future.result()
                except BrokenProcessPool:
                    lost.append(task)
                    continue
                done(task, row)
    except KeyboardInterrupt:
        restore()
        for child in multiprocessing.active_children():  # a Ctrl-C sent to the sweep alone: to its runs too
            with contextlib.suppress(OSError):
                os.kill(child.pid, signal.SIGINT)
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    finally:
        restore()
    pool.shutdown(wait=True)
    return sorted(lost, key=lambda t: t["run"])


def run_ray(tasks: list[dict], address: str | None, jobs: int | None, done: Done) -> None:
    """Run each task as a Ray task (one CPU each) on the cluster at `address` (None: a local one
    started here, or the one Ray is already connected to); its recording and log come back as
    bytes and are written where the task says."""
    try:
        import ray
    except ImportError:
        raise SweepError("--ray needs Ray: pip install 'iotad[ray]'") from None
    started = False
    if not ray.is_initialized():
        options = {"include_dashboard": False, "log_to_driver": False}
        if address:
            options["address"] = address
        elif jobs:
            options["num_cpus"] = jobs
        try:
            ray.init(**options)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise SweepError(f"--ray {address or ''}: cannot start or reach Ray: {exc}".replace("  ", " ")) from None
        started = True
    remote = ray.remote(num_cpus=1, max_retries=0)(_ray_run)
    pending = {remote.remote(task): task for task in tasks}
    try:
        while pending:
            finished, _ = ray.wait(list(pending), num_returns=1)
            for ref in finished:
                task = pending.pop(ref)
                try:
                    row, recording, log = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a worker or node lost: this run's row
                    done(task, _died(task, f"its Ray task failed: {type(exc).__name__}: "
                                           f"{' '.join(str(exc).split())[:300]}"))
                    continue
                for path, data in ((task["recording"], recording), (task["log"], log)):
                    if data is not None:
                        Path(path).parent.mkdir(parents=True, exist_ok=True)
                        Path(path).write_bytes(data)
                done(task, row)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()


def _ray_run(task: dict) -> tuple[dict, bytes | None, bytes | None]:
    """A Ray task: the run in a folder of the machine it lands on; its files go back whole."""
    with tempfile.TemporaryDirectory(prefix="iotad-sweep-") as folder:
        here = dict(task, recording=str(Path(folder) / "run.mcap"), log=str(Path(folder) / "run.log"))
        row = run_one(here)
        files = [Path(here[key]).read_bytes() if Path(here[key]).is_file() else None for key in ("recording", "log")]
    return row, files[0], files[1]
