"""The recorder as a process of its own: record until SIGINT or SIGTERM, stamping a ready file as
its sign of life. `python -m iotad.recording.recorder_process` is how a launcher starts the
recorder of a run (a module of this layer: the launcher, a layer below, names it and imports
nothing of it); `iotad record` runs the same loop (`record_until_stopped`).

The ready file is created once the recorder listens, then stamped every half second with an
explicit time (`stamp`): a launcher that sees it stop changing kills the recorder as frozen.
Not `os.utime(path)` with no time: on some file systems (hostfs in user-mode Linux, where the
CAN tier runs) that leaves the time unchanged, and a busy recorder looked frozen.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Callable

from iotad.node_host import wire
from iotad.node_host.stop_signals import StopSignals
from iotad.recording.recorder import Recorder

BEAT = 0.5  # s between stamps of the ready file


def stamp(path: str | os.PathLike) -> None:
    """Set `path`'s modification time to now, given explicitly (see the module's docstring)."""
    now = time.time_ns()
    try:
        os.utime(path, ns=(now, now))
    except OSError:
        pass


def stop_on_signals() -> StopSignals:
    """SIGINT or SIGTERM: the clean stop of a recorder process. Not a threading.Event set in the
    handler: that deadlocked a recorder whose SIGINT came while it waited on the Event
    (iotad.node_host.stop_signals), and its file was never finished."""
    return StopSignals((signal.SIGINT, signal.SIGTERM))


def record_until_stopped(recorder: Recorder, stop: StopSignals, *, ready_file: str | None = None,
                         deadline: float | None = None, said: Callable[[str], None] | None = None) -> dict:
    """Record with a started `recorder` until `stop` is set, `deadline` (time.monotonic()) passes
    or a write fails; then stop it (its file finished) and return its stats. `ready_file` is
    created now and stamped while it records; `said` gets the line that says what it records."""
    try:
        if ready_file:
            Path(ready_file).write_text(str(recorder.output))
        if said is not None:
            said(f"recording {' '.join(recorder.keys)} -> {recorder.output} (Ctrl-C to stop)")
        while not stop.is_set() and recorder.failed is None:  # a write error ends the recording: exit, say why
            timeout = BEAT if deadline is None else min(BEAT, max(0.0, deadline - time.monotonic()))
            stop.wait(timeout)
            if ready_file:  # a sign of life for the launcher, which restarts a frozen recorder
                stamp(ready_file)
            if deadline is not None and time.monotonic() >= deadline:
                break
    finally:
        stats = recorder.stop()
    return stats


def main(argv: list[str] | None = None) -> int:
    """A launcher's recorder: the whole system from its nodes' traces, to -o, connected to the hub."""
    parser = argparse.ArgumentParser(prog="python -m iotad.recording.recorder_process", description=__doc__)
    parser.add_argument("system", help="the system's name (records iota/SYSTEM/**)")
    parser.add_argument("-o", "--output", required=True, help="the MCAP file (the launcher has checked it)")
    parser.add_argument("--system-file", help="the system file stored in the recording")
    parser.add_argument("--connect", action="append", default=[], help="the hub's endpoint (repeatable)")
    parser.add_argument("--ready-file", required=True, help="created once subscribed, then stamped as it lives")
    parser.add_argument("--force", action="store_true", help="split: numbered files may replace an earlier run's")
    parser.add_argument("--max-size", type=int, default=None, help="split: bytes per file")
    parser.add_argument("--max-duration", type=float, default=None, help="split: seconds per file")
    parser.add_argument("--run", type=json.loads, default=None,
                        help="JSON: whose recording this is in a run spread over hosts (metadata `run`)")
    parser.add_argument("--nodes", default=None,
                        help="comma-separated: record only these nodes' traces (a host's own recording)")
    args = parser.parse_args(argv)
    stop = stop_on_signals()
    try:
        recorder = Recorder([f"{wire.PREFIX}/{args.system}/**"], args.output, system_file=args.system_file,
                            connect=args.connect, background=True,  # yield the CPU to the nodes
                            from_traces=True,  # one wake-up per trace burst, not per message
                            max_size=args.max_size, max_duration=args.max_duration, replace=args.force,
                            run=args.run, nodes=None if args.nodes is None else args.nodes.split(","))
        recorder.start(lambda: not stop.is_set())  # its hub is up: this waits only for credentials
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        print(f"recorder: error: {exc}", file=sys.stderr, flush=True)
        return 2
    except Exception as exc:  # noqa: BLE001 - zenoh said no
        print(f"recorder: error: cannot start recording: {str(exc).split(' at /', 1)[0]}", file=sys.stderr, flush=True)
        return 2
    try:
        stats = record_until_stopped(recorder, stop, ready_file=args.ready_file,
                                     said=lambda line: print(line, file=sys.stderr, flush=True))
    finally:
        stop.close()
    print(f"recorded {stats['written']} messages to {recorder.output}; {stats['gaps']} sequence gaps "
          f"({stats['missing']} missing)", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
