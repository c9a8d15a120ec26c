"""Recording a virtual run in a second process, so that writing MCAP costs the engine one core less.

`iotad run --virtual -o FILE` spends about a quarter of its time turning events into MCAP
messages (`EngineRecorder`: channel look-ups, packing, the chunk's index). On a machine with a
second core that work can run beside the engine: the engine's process only packs each event
(one msgpack call, about a microsecond) and pipes batches of them to this process, which runs
the same `EngineRecorder` on the same events and writes the same file.

The pipe carries msgpack objects one after the other. An event is a map (the engine's event as
it is); anything else is a command, an array whose first element names it:

    ["open", PATH]          first: the file to write; the writer answers `ready` on its stdout
                            (or prints why it cannot write it on stderr, and exits 2)
    ["header", HEADER]      `recording_header(...)`: the specs and metadata
    ["events", BYTES]       a batch of events, the pickle of their list, made of plain Python
                            objects only (None, bool, int, float, str, bytes, list, tuple, dict of
                            exactly those classes): for the engine's process a third less work
                            than packing each event with msgpack (one call per batch, and each
                            key and name written once, then referred to). The writer reads the
                            same objects back and packs them as it would the maps; a batch with
                            anything else (a numpy float, an IntEnum) goes as one map per event,
                            which msgpack packs as it always did
    ["metadata", NAME, MAP] a metadata record (the run's end, or the error that broke it off)
    ["finish"]              the run is over: write the summary and exit 0

The writer is started before the system is built, so that its own start-up (about 0.1 s of
imports) overlaps that; the file is named later, once the run's input has been found good (a
wrong input never costs an old recording). Its input ending before `open` is no error: the run
did not get that far. It ignores Ctrl-C (the engine's process stops the run, then finishes the
recording), and if its input ends without `finish` (the engine's process was killed, or broke
off in the middle of a batch) it still writes a whole file, with what came and an
`iotad.run_error` record saying that the run was cut short, so `iotad check` does not pass it.

    python -m iotad.recording.writer_process      (started by `RecordingProcess`)
"""
from __future__ import annotations

import fcntl
import io
import os
import pickle
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, Iterator

import msgpack

from iotad.recording.engine_sink import EngineRecorder
from iotad.recording.mcap_format import RUN_ERROR, RecordingError
from iotad.recording.mcap_sink import McapSink

BATCH = 256          # events per write to the pipe (~40 KB): well under what the pipe holds
PIPE_SIZE = 1 << 20  # bytes the pipe holds (Linux's default most, /proc/sys/fs/pipe-max-size)
READ_SIZE = 1 << 20  # bytes the writer reads at a time
CUT_SHORT = "the run's process ended without finishing its recording (killed, or stopped hard)"
HARD_STOP_WAIT = 5.0  # s a writer gets to finish its file after a hard stop


class _NotPlain(Exception):
    """A batch holds an object `_plain_pickle` does not take."""


class _PlainPickler(pickle.Pickler):
    """Pickles None, bool and exactly int, float, str, bytes, list, tuple and dict (with set and
    frozenset, the objects the C pickler handles without asking `reducer_override`; msgpack
    refuses a set on either side); anything else raises `_NotPlain`."""

    def reducer_override(self, obj: Any) -> Any:
        raise _NotPlain(type(obj).__name__)


def _plain_pickle(value: Any) -> bytes:
    out = io.BytesIO()
    _PlainPickler(out, protocol=pickle.HIGHEST_PROTOCOL).dump(value)
    return out.getvalue()


class _PlainUnpickler(pickle.Unpickler):
    """Reads what `_PlainPickler` wrote: no class is ever looked up (nor a module imported)."""

    def find_class(self, module: str, name: str) -> Any:
        raise pickle.UnpicklingError(f"the engine's batch names a class ({module}.{name}): not plain data")


class WriterFailed(RecordingError):
    """The writer process could not open its file, or stopped: the message is its own words."""


class RecordingProcess:
    """An Engine sink that hands every event to a writer process (`python -m
    iotad.recording.writer_process`); in the engine's process an event costs one msgpack call.

    Start it early (the writer's start-up then overlaps building the system), `open(output)`
    before the run (a file it cannot write is an error then, not after the run), `begin(header)`
    with the system's `recording_header`, then use it as a sink; `add_metadata` and `finish` are
    `McapSink`'s. `finish` waits for the writer to write everything and raises `WriterFailed` if
    it did not; `close` ends a writer that was never needed."""

    def __init__(self):
        self.output: Path | None = None
        self._errors = tempfile.TemporaryFile()  # the writer's stderr, read only if it fails
        package_root = str(Path(__file__).resolve().parents[2])  # runs from a checkout too
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")])))
        self._process = subprocess.Popen(
            [sys.executable, "-m", "iotad.recording.writer_process"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._errors, env=env,
            start_new_session=True)  # a Ctrl-C at the terminal is the engine process's to handle
        self._fd = self._process.stdin.fileno()
        # The pipe is the queue between the two: with Linux's default of 64 KB the engine would
        # wait for the writer at every few batches, and the two would take turns instead of
        # running side by side. A megabyte holds ~7,000 events, some 60 ms of a busy run.
        try:
            fcntl.fcntl(self._fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), PIPE_SIZE)
        except OSError:
            pass  # a smaller limit (pipe-max-size): slower, not wrong
        self._pack = msgpack.Packer(use_bin_type=True).pack
        self._parts: list[bytes] = []
        self._events: list[dict] = []  # events not yet in `_parts` (an event's value is never
        # changed once emitted: the engine's own trace keeps them so too)
        self._torn = False      # a write was broken off in the middle: the stream ends there
        self._failed: str | None = None
        self.finished = False

    # ---------------------------------------------------------------- the engine's side
    def open(self, output: str | Path) -> None:
        """The file to write; returns once the writer has opened it, `WriterFailed` (its reason,
        "cannot write PATH: ...") if it cannot."""
        self.output = Path(output)
        self._parts.append(self._pack(["open", str(output)]))
        try:
            self._send()
            said = self._process.stdout.readline()
        except WriterFailed:
            said = b""
        if said != b"ready\n":
            self.close()
            words = self._last_words()
            raise WriterFailed(f"cannot write: {words}" if words else
                               f"the recording's writer process stopped before it opened the file ({self._how()})")

    def begin(self, header: dict[str, Any]) -> None:
        self._parts.append(self._pack(["header", header]))
        self._send()

    def __call__(self, event: dict) -> None:
        events = self._events
        events.append(event)
        if len(events) >= BATCH:
            self._send()

    def add_metadata(self, name: str, data: dict[str, Any]) -> None:
        self._batch()  # the events before it go first
        self._parts.append(self._pack(["metadata", name, data]))
        self._send()

    def _batch(self) -> None:
        """The events not yet packed into `_parts`, as one `events` command (or one map each)."""
        events = self._events
        if not events:
            return
        self._events = []
        try:
            self._parts.append(self._pack(["events", _plain_pickle(events)]))
        except _NotPlain:  # msgpack writes such a value as its base type (a numpy float as a float)
            self._parts += map(self._pack, events)

    def finish(self) -> None:
        """Everything to the writer, then wait for it to write the summary and exit."""
        if self.finished:
            return
        self.finished = True
        try:
            if not self._torn and self._failed is None:
                self._batch()
                self._parts.append(self._pack(["finish"]))
                self._send()
        finally:
            code = self.close()
        if self._failed is not None or code != 0:
            raise WriterFailed(self._failed or self._reason())

    def close(self) -> int:
        """End the writer's input and wait for it to exit (at once, if it was never `open`ed);
        its exit status. After a stream broken off (a second Ctrl-C), or a Ctrl-C during the
        wait, the writer gets `HARD_STOP_WAIT` seconds to finish its file and is then killed (a
        stalled disk must not hold the command): `iotad recover` reads what it left."""
        for stream in (self._process.stdin, self._process.stdout):
            try:
                stream.close()
            except OSError:
                pass
        try:
            return self._process.wait(HARD_STOP_WAIT if self._torn else None)
        except (subprocess.TimeoutExpired, KeyboardInterrupt):
            self._process.kill()
            code = self._process.wait()
            print(f"iotad: the recording's writer did not finish {self.output} in time and was stopped; "
                  f"'iotad recover {self.output}' reads what it wrote", file=sys.stderr)
            return code

    @property
    def torn(self) -> bool:
        """A write was broken off (a second Ctrl-C): the writer marks the file cut short."""
        return self._torn

    def _send(self) -> None:
        """The batch to the pipe. An exception in the middle (a second Ctrl-C: `iotad run
        --virtual` takes the first one as a request, between steps) leaves the stream torn:
        nothing more is sent, and the writer, reading its end mid-event, marks the file cut short."""
        if self._failed is not None:
            raise WriterFailed(self._failed)
        if self._torn:
            return
        self._batch()
        self._torn = True  # until every byte is out
        data = memoryview(b"".join(self._parts))
        self._parts = []
        try:
            while data:
                data = data[os.write(self._fd, data):]
        except OSError:  # EPIPE: the writer is gone
            self._process.wait()
            self._failed = self._reason()
            raise WriterFailed(self._failed) from None
        self._torn = False

    def _last_words(self) -> str:
        self._errors.seek(0)
        lines = [line for line in self._errors.read().decode(errors="replace").splitlines() if line.strip()]
        return lines[-1] if lines else ""

    def _how(self) -> str:
        code = self._process.returncode
        return (f"killed by signal {-code}" if code is not None and code < 0
                else f"exit status {code}" if code is not None else "still running")

    def _reason(self) -> str:
        """The writer's own last words, or how it ended."""
        said = self._last_words() or f"it said nothing ({self._how()})"
        return f"the recording's writer process stopped: {said}; {self.output} holds what it wrote before"


# -------------------------------------------------------------------- the writer's side
def main(argv: list[str] | None = None) -> int:
    if (sys.argv[1:] if argv is None else argv):
        print("python -m iotad.recording.writer_process takes no arguments: `iotad run --virtual` starts it "
              "and names its file on its input", file=sys.stderr)
        return 2
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    items = _items(sys.stdin.buffer.fileno())
    first = next(items, None)
    if first is None:
        return 0  # the run ended before it had a recording to write
    if not (isinstance(first, list) and len(first) == 2 and first[0] == "open" and isinstance(first[1], str)):
        print(f"the first command must be [\"open\", PATH], got {first!r:.80}", file=sys.stderr)
        return 2
    output = first[1]
    try:
        sink = McapSink(output)
        # the file's magic and header on disk at once: a writer killed before its first chunk
        # leaves a recording `iotad info` calls incomplete (and `iotad recover` reads), not an
        # empty file that is no recording at all
        sink.flush()
    except OSError as exc:
        print(exc.strerror or str(exc), file=sys.stderr)
        return 2
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    try:
        finished, last_t = _write_events(sink, items)
        if not finished:
            sink.add_metadata(RUN_ERROR, {"error": CUT_SHORT, "t": last_t})
        sink.finish()
    except Exception as exc:  # noqa: BLE001 - a full disk, or a fault: one line for the engine's side
        print(f"{type(exc).__name__}: {exc.strerror if isinstance(exc, OSError) and exc.strerror else exc}",
              file=sys.stderr)
        try:
            sink.add_metadata(RUN_ERROR, {"error": f"the recording's writer failed: {type(exc).__name__}: {exc}"})
            sink.finish()
        except Exception:  # noqa: BLE001 - the file could not be finished: `iotad recover` reads it
            pass
        return 1
    return 0


def _items(fd: int) -> Iterator[Any]:
    """The msgpack objects on `fd`, one by one, until its end (a cut-off last one is dropped)."""
    unpacker = msgpack.Unpacker(raw=False, strict_map_key=False)
    while True:
        data = os.read(fd, READ_SIZE)
        if not data:
            return
        unpacker.feed(data)
        yield from unpacker


def _write_events(sink: McapSink, items: Iterator[Any]) -> tuple[bool, float]:
    """Commands and events until `finish` or the input's end: (finished, the last event's time
    in seconds, as `iotad.run_error` gives it)."""
    recorder = None
    t = 0.0
    for item in items:
        if item.__class__ is dict:
            if recorder is None:
                raise ValueError("an event came before the recording's header")
            recorder(item)
            t = item["t"]
        elif item[0] == "events":
            if recorder is None:
                raise ValueError("an event came before the recording's header")
            for event in _PlainUnpickler(io.BytesIO(item[1])).load():
                recorder(event)
                t = event["t"]
        elif item[0] == "header":
            recorder = EngineRecorder.from_header(sink, item[1])
        elif item[0] == "metadata":
            sink.add_metadata(item[1], item[2])
        elif item[0] == "finish":
            return True, t * recorder.time_unit if recorder else t
        else:
            raise ValueError(f"unknown command {item[0]!r} from the engine's process")
    return False, t * recorder.time_unit if recorder else t


if __name__ == "__main__":
    sys.exit(main())
