"""The recorder of a run, supervised like a node: started before any node (and waited for until it
listens), watched for a sign of life, replaced in a numbered continuation file if it dies or
freezes, stopped last. Its process is the recording layer's `python -m
iotad.recording.recorder_process` (named, not imported: that layer is above this one).

Sign of life: the recorder stamps its ready file every half second. The supervisor notes, on its
own monotonic clock, when it last saw the stamp change, so that neither the file system's time
resolution (whole seconds on hostfs) nor a clock between two kernels (user-mode Linux) counts.
A recorder is frozen after no change for its allowance: the system's `start_timeout` while the
system starts (its nodes importing on the same cores can starve a recorder of CPU), then twice
its `heartbeat_timeout` (at least RECORDER_STALL s), as a node is judged by its heartbeats.
"""
from __future__ import annotations

import json
import queue
import signal
import sys
import time
from pathlib import Path
from typing import Callable

from iotad.launcher.options import RecordingOptions
from iotad.launcher.processes import Child, describe_exit, log_tail, stop_all
from iotad.launcher.run.recording_paths import next_continuation, unwritable
from iotad.launcher.system.system_file import System

MIN_FREE_BYTES = 16 * 2**20   # refuse to start a recording on a file system with less free space
RECORDER_RESTARTS = 3         # new recorders after the first one died, before recording stops
RECORDER_STALL = 5.0          # s without a sign of life before a running recorder is killed, at least
RECORDER_MODULE = "iotad.recording.recorder_process"


class RecordingError(Exception):
    """The recording cannot begin (unwritable, or the recorder did not come up): one line."""


class RecorderSupervisor:
    """The recorder of one run: `start()` before the nodes, `supervise()` on every turn of the
    launcher's loop, `exited()` when its process ends, `stop()` after the nodes.

    `events`: the launcher's queue, which gets ("recorder", pid, code) when a recorder exits.
    `say(text)`: a line for the status view. `announce(event, text, code=None, **extra)`: a
    launcher event (on `@launcher`, so that the recording itself holds the news)."""

    def __init__(self, system: System, options: RecordingOptions, *, hub: list[str], run_dir: Path,
                 env: dict[str, str] | None, events: queue.Queue, say: Callable[[str], None],
                 announce: Callable[..., None], run_info: dict | None = None, nodes: list[str] | None = None):
        """`run_info`: a run spread over hosts, whose recording this is (metadata `run`, for `iotad
        merge`); `nodes`: another host's recording records only its own nodes (None: every node)."""
        self.system, self.options, self.hub, self.run_dir, self.env = system, options, hub, run_dir, env
        self.events, self.say, self.announce = events, say, announce
        self.child: Child | None = None
        self.recording: Path | None = None        # the file being written now
        self.recordings: list[Path] = []          # every file this run wrote, in order
        self.lost: str | None = None              # why recording stopped before the run did
        self.restarts = 0
        self._ready: Path | None = None           # a restarted recorder's ready file, until it exists
        self._beat: Path | None = None            # the running recorder's ready file, stamped as it lives
        self._stamp: int | None = None            # the beat's last modification time seen
        self._life = 0.0                          # time.monotonic() of its last sign of life (or its start)
        self._frozen = 0.0                        # s of silence of a recorder killed as frozen
        self._stopping = False
        self._since = 0.0                         # time.time() as the recording began
        self._ended = ""                          # how the last recorder that died ended ("killed by SIGKILL")
        self.run_info, self.nodes = run_info, nodes

    # ------------------------------------------------------------------ allowances
    def start_allowance(self) -> float:
        """Seconds a recorder may take to listen, or stay silent while the system starts."""
        return max(10.0, self.system.start_timeout)

    def heartbeat_allowance(self) -> float:
        """Seconds of silence after which a recorder of a running system is frozen."""
        return max(RECORDER_STALL, 2 * self.system.heartbeat_timeout)

    # ------------------------------------------------------------------ life cycle
    def start(self) -> None:
        """Start the recorder and wait until it has subscribed; `RecordingError` if it cannot."""
        output = Path(self.options.path)
        self._since = time.time()  # files older than this are an earlier run's (--force replaces them)
        problem = unwritable(output, make_folder=True, min_free_bytes=MIN_FREE_BYTES)
        if problem:
            raise RecordingError(f"cannot record to {output}: {problem}; choose another file with -o, "
                                 "or run without a recording (--no-record)")
        ready = self._spawn(output)
        deadline = time.monotonic() + self.start_allowance()
        while not ready.exists() and self.child.running() and time.monotonic() < deadline:
            time.sleep(0.02)
        if not ready.exists():
            recorder, self.child = self.child, None
            stop_all([recorder], 1.0, 1.0)
            why = describe_exit(recorder.code) if recorder.code is not None else \
                f"not subscribed after {deadline - recorder.started_at:.0f} s"
            raise RecordingError(f"the recorder did not start ({why}){log_tail(recorder)}\n"
                                 "run without a recording with --no-record")
        self._ready = None
        self.recording = output
        self.recordings.append(output)
        self.say(f"recording to {output} (recorder pid {self.child.pid})")

    def _spawn(self, output: Path) -> Path:
        system, options = self.system, self.options
        ready = self.run_dir / f"recorder{len(self.recordings)}.ready"
        ready.unlink(missing_ok=True)
        argv = [sys.executable, "-m", RECORDER_MODULE, system.name, "-o", str(output),
                "--system-file", str(system.path), "--ready-file", str(ready)]
        if options.force:  # split members over an earlier run's files too (the first file the CLI checked)
            argv.append("--force")
        if options.max_size is not None:
            argv += ["--max-size", str(options.max_size)]
        if options.max_duration is not None:
            argv += ["--max-duration", repr(float(options.max_duration))]
        if self.run_info is not None:
            argv += ["--run", json.dumps(self.run_info)]
        if self.nodes is not None:
            argv += ["--nodes", ",".join(self.nodes)]
        for endpoint in self.hub:  # a client of the hub, which relays each node's first sample
            argv += ["--connect", endpoint]
        # If the launcher is killed (-9), the recorder is interrupted, not killed: it writes the
        # file's summary and footer, and the recording stays complete up to that moment
        self.child = Child("recorder", argv, log=self.run_dir / "recorder.log", env=self.env,
                           on_exit=lambda child, code: self.events.put(("recorder", child.pid, code)),
                           death_signal=signal.SIGINT)
        self.child.start()
        self._ready = self._beat = ready
        self._stamp, self._life = None, time.monotonic()
        return ready

    def supervise(self, system_starting: bool) -> None:
        """Kill a recorder that gave no sign of life for its allowance; say once a restarted one
        listens (so that the new file holds the news of the old one's end)."""
        self._check_life(system_starting)
        if self._ready is not None and self._ready.exists() and self.child is not None:
            self._ready = None
            # the news of the last one's end too: while no recorder ran, no file heard it
            self.announce("recorder", f"recorder: restarted (pid {self.child.pid}), recording continues in "
                                      f"{self.recording}; the gap since {self.recordings[-2]} ended is lost",
                          file=str(self.recording), after=str(self.recordings[-2]), ended=self._ended)

    def _check_life(self, system_starting: bool) -> None:
        beat, recorder = self._beat, self.child
        if beat is None or recorder is None or not recorder.running() or self._stopping:
            return  # a stopping recorder writes its file's end: no sign of life then
        now = time.monotonic()
        try:
            stamp = beat.stat().st_mtime_ns
        except OSError:
            stamp = None  # not there yet: a restarted recorder still starting
        if stamp is not None and stamp != self._stamp:
            self._stamp, self._life = stamp, now
            return
        listening = stamp is not None
        allowance = self.heartbeat_allowance() if listening and not system_starting else \
            max(self.start_allowance(), self.heartbeat_allowance())
        if now - self._life > allowance:
            self._frozen = now - self._life
            recorder.signal(signal.SIGKILL)
            self._life = float("inf")  # do not kill twice: its exit comes next

    def exited(self, pid: int, code: int) -> None:
        """The recorder ended while the system runs: name the cut file, continue in a new one."""
        recorder = self.child
        if recorder is None or recorder.pid != pid:
            return  # one the launcher stopped itself
        self.child = None
        cut = self.recording
        self.recording = None
        uptime = time.monotonic() - recorder.started_at
        state = "is complete" if code == 0 else f"was cut short: 'iotad recover {cut}' makes it whole"
        frozen, self._frozen = self._frozen, 0.0
        why = f" (frozen: no sign of life for {frozen:.1f} s)" if frozen else ""
        self._ended = f"{describe_exit(code)}{why} after {uptime:.1f} s"
        self.announce("recorder", f"recorder: {describe_exit(code)}{why} after {uptime:.1f} s; {cut} {state}"
                                  f"{log_tail(recorder)}", code=code, file=str(cut))
        if self._stopping:
            self.lost = f"the recorder ended with {describe_exit(code)} before the stop"
            return
        if self.restarts >= RECORDER_RESTARTS:
            self._lose(f"the recorder died {self.restarts + 1} times")
            return
        self.restarts += 1
        # an earlier run's file is kept, as `-o` keeps one (--force: replaced); this run's never
        output = next_continuation(self.recordings[0], self.restarts, self._since if self.options.force else None)
        problem = unwritable(output, make_folder=True, min_free_bytes=MIN_FREE_BYTES)
        if problem:
            self._lose(f"cannot record to {output}: {problem}")
            return
        try:
            self._spawn(output)
        except OSError as exc:  # out of processes, of file descriptors...
            self.child = None
            self._lose(f"cannot start a new recorder: {exc}")
            return
        self.recording = output
        self.recordings.append(output)
        self.say(f"recorder: restarting (pid {self.child.pid}) to record to {output}")

    def _lose(self, why: str) -> None:
        self.lost = why
        self.announce("recorder", f"recorder: RECORDING STOPPED: {why}; the nodes keep running", code=1)

    def stopping(self) -> None:
        """The run stops: from now on the recorder's silence and its exit are the stop's."""
        self._stopping = True

    def stop(self) -> None:
        """Stop the recorder (after the nodes: it saw them go); a failed stop makes it lost."""
        if self.child is None:
            return
        recorder, self.child = self.child, None  # its exit is ours, not a death
        time.sleep(0.1)  # let the last events reach the recorder before it closes its file
        stop_all([recorder], 5.0, 2.0)
        if recorder.code not in (0, None):
            self.lost = self.lost or f"the recorder ended with {describe_exit(recorder.code)}"
            self.say(f"warning: the recorder ended with {describe_exit(recorder.code)}; "
                     f"'iotad recover {self.recording}' makes the file whole{log_tail(recorder)}")

    # ------------------------------------------------------------------ reporting
    @property
    def incomplete(self) -> bool:
        """Part of the run is not recorded: a recorder died (a gap between files) or recording stopped."""
        return bool(self.lost or self.restarts)

    def summary_lines(self) -> list[str]:
        lines = []
        if len(self.recordings) == 1 and not self.lost:
            lines.append(f"  recording: {self.recordings[0]}")
        elif len(self.recordings) == 1:
            lines.append(f"  recording (cut short: 'iotad recover' it): {self.recordings[0]}")
        elif self.recordings:
            lines.append(f"  recording in {len(self.recordings)} files (the recorder died): "
                         + ", ".join(str(p) for p in self.recordings)
                         + "; what happened between them is lost, so the run does not exit 0")
        if self.lost:
            lines.append(f"  RECORDING INCOMPLETE: {self.lost}")
        return lines


__all__ = ["RECORDER_MODULE", "RECORDER_STALL", "RecorderSupervisor", "RecordingError"]
