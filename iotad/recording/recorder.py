"""The recorder: subscribes to a running system over zenoh and writes every event to MCAP.

Samples wait in zenoh's Rust FIFOs (one per key expression; no Python callback per sample) and
one writer thread owns the MCAP file: it takes them (log time = that moment), maps keys to
channels, reads the sender's `[sequence, send_time_ns]` attachment (publish time, gap
detection), asks each new node for its `@spec`, and closes the chunk in progress every
`flush_period` seconds, so that a SIGKILLed recorder loses at most that much.

Two modes. Direct: subscribe to the keys given and record every sample on its key; on a machine
with few cores every message then also wakes the recorder's process, which the real-time nodes
pay for in latency. Trace-sourced (`from_traces`, what `iotad run` uses): subscribe only to the
nodes' `@trace` keys (bursts, one sample and one wake-up per node and trace period; each
burst is split into one message per event, so a recording is the same as if each had come alone), `@launcher` and
`@heartbeat`, and write each message from the trace event that describes it: an output on its
key with the sequence number and send time the node published it with; an input that no node's
output explains (`iotad pub`, a foreign publisher) on the key it arrived on, with the sender's
attachment. It records what the nodes sent and saw: a message nobody received is only recorded
in direct mode, and a message reaches the file one trace period (20 ms by default) late.

Split recordings (`max_size`, `max_duration`, like rosbag2's): at the first flush after a file
has reached either bound, the file is finished (summary, footer) and the next one begins, each
a whole recording on its own (metadata, system file, every spec known so far). `output` is then
the set file: no messages, only the list of members `NAME_0.mcap`, `NAME_1.mcap`... in the same
folder, rewritten before each member is created; `mcap_reader.read_recording(output)` reads the set
as one recording. Sequence gaps are tracked across the files, as in one.

Memory stays flat over a long run: the writer keeps one chunk and the chunk indexes go to a temp
file (`McapSink`); the FIFOs hold at most `fifo_capacity` samples per key expression.
"""
from __future__ import annotations

import functools
import json
import os
import threading
import time
import uuid
from pathlib import Path
from typing import Any, Callable, Iterable

import msgpack
import zenoh

from iotad.node_host import wire
from iotad.node_host.can_port import KEY_PREFIX as CAN_KEY_PREFIX
from iotad.node_host.credentials import for_endpoints
from iotad.launcher.run.recording_paths import continuation_path, unused_recording_path
from iotad.recording.mcap_format import FORMAT, GAP_TOPIC, MALFORMED_TOPIC, packb, trace_event_problem
from iotad.recording.mcap_sink import channel_schemas, McapSink, schema_for_topic, write_set_file
from iotad.node_host.transport import DEFAULT_LISTEN, open_session
from iotad.kernel.clock import CLOCK_SKEW_ENV, wall
from iotad.launcher.system.declaration import Declaration, SystemFileError, read_declaration

_MAPS = ("/" + wire.LAUNCHER, "/" + wire.HEARTBEAT)
_TRACE = "/" + wire.TRACE  # the end of every node's @trace key  # keys whose payload every reader takes for a msgpack map
NICENESS = 10  # a tenth of a normal process's CPU share when both want the CPU
# zenoh's retries of a `connect` endpoint: every 100 ms, so that a recorder started before its
# system's hub joins it as soon as the hub listens, before the nodes start talking
CONNECT_RETRY = {"connect/retry": {"period_init_ms": 100, "period_max_ms": 100, "period_increase_factor": 1.0}}
_UNDECODABLE = object()  # what `_decoded` gives for a payload that is no msgpack
_NEVER = 1 << 62  # the next `seq` of a stream whose last burst could not be counted: no gap is seen


def yield_cpu(threads: Iterable[int] | None = None, niceness: int = NICENESS) -> str:
    """Lower the CPU priority of this process (every thread of it, zenoh's included) to
    `niceness`. Returns what was done, for the log.

    A logger should give way to the real-time nodes: on a machine with few cores the recorder
    is woken for every event it records and competes with the nodes' own wake-ups. Not
    SCHED_IDLE, and not the weakest nice level: a recorder starved by busy nodes would keep
    events in memory for longer than a kill may lose (`flush_period`), so it keeps a share."""
    if threads is None:
        try:
            threads = [int(name) for name in os.listdir("/proc/self/task")]
        except OSError:
            threads = [0]
    done = "unchanged"
    for tid in threads:
        try:
            if os.getpriority(os.PRIO_PROCESS, tid) < niceness:
                os.setpriority(os.PRIO_PROCESS, tid, niceness)  # Linux: per thread
            done = f"nice {niceness}"
        except OSError:
            pass
    return done


def log_clock() -> Callable[[], int]:
    """The clock a recorder's log times are on, in ns: the one origins are in (`wall()`), so that a
    host's recording moves onto the hub's clock by the host's measured offset (`iotad merge`).
    That is `time.time_ns` itself (no cost in the hot loop) unless a drill makes this host's
    clock wrong on purpose (IOTAD_CLOCK_SKEW and the like: docs/hosts.md)."""
    if not any(os.environ.get(name) for name in (CLOCK_SKEW_ENV, "IOTAD_CLOCK_DRIFT")):
        return time.time_ns
    return lambda: round(wall() * 1e9)


wall_ns = log_clock()


def expand_keys(keys: Iterable[str]) -> list[str]:
    """`iota/<sys>/**` does not match `@` chunks in zenoh: widen it to every key of the system."""
    out: list[str] = []
    for key in keys:
        parts = key.split("/")
        if len(parts) == 3 and parts[0] == wire.PREFIX and parts[2] == "**" and "*" not in parts[1]:
            wanted = wire.subscription_keys(parts[1])
        else:
            wanted = [key]
        out += [k for k in wanted if k not in out]
    return out


def trace_keys(system: str, nodes: list[str] | None = None, every_beat: bool = False) -> list[str]:
    """What a trace-sourced recorder subscribes to: no channel key, so no wake-up per message.
    `nodes`: only their traces (and the launchers' events), not every node's; their heartbeats
    too, or every node's with `every_beat` (the hub's, when a host keeps its traces home)."""
    if nodes is not None:
        beats = [wire.every_node(system, wire.HEARTBEAT)] if every_beat else \
            [wire.node_key(system, node, wire.HEARTBEAT) for node in nodes]
        return [*(wire.node_key(system, node, wire.TRACE) for node in nodes), wire.launcher_key(system), *beats]
    return [wire.every_node(system, wire.TRACE), wire.launcher_key(system), wire.every_node(system, wire.HEARTBEAT)]


def read_system_file(path: str | Path) -> Declaration:
    """The declaration of a system file, for what a recorder needs of it (its name, nodes, time
    unit, hub, text): read whole, not checked. ValueError where it is no TOML."""
    try:
        return read_declaration(path)
    except SystemFileError as exc:
        raise ValueError(str(exc)) from None


class Recorder:
    """Record `keys` to `output` until `stop()`. `stats` counts what came and what was written."""

    def __init__(self, keys: Iterable[str], output: str | Path, *, system_file: str | Path | None = None,
                 connect: Iterable[str] = (), listen: Iterable[str] | None = None,
                 flush_period: float = 0.05, spec_timeout: float = 0.5, query_specs: bool = True,
                 fifo_capacity: int = 65536, background: bool = False, from_traces: bool = False,
                 max_size: int | None = None, max_duration: float | None = None, replace: bool = False,
                 run: dict | None = None, nodes: Iterable[str] | None = None):
        # a launcher's recorder of a run spread over hosts: whose recording this is (host, hub or
        # not, the run's origin, the host's clock offset to the hub), for `iotad merge`
        self.run = dict(run) if run else None
        self.declaration = None if system_file is None else read_system_file(system_file)
        self.system_text = None if self.declaration is None else self.declaration.text
        self.system = None if self.declaration is None else self.declaration.name
        keys = list(keys)
        if not keys and self.system:
            keys = [f"{wire.PREFIX}/{self.system}/**"]
        if not keys:
            raise ValueError("nothing to record: give key expressions or a system file")
        self.keys = expand_keys(keys)
        if self.system is None:
            parsed = self.keys[0].split("/")
            if len(parsed) > 1 and parsed[0] == wire.PREFIX and "*" not in parsed[1]:
                self.system = parsed[1]
        self.from_traces = from_traces
        if from_traces:
            whole = [f"{wire.PREFIX}/{self.system}/**"]
            if self.system is None or any(expand_keys([k]) != expand_keys(whole) for k in keys):
                raise ValueError("a trace-sourced recording records one whole system: give 'iota/SYS/**' "
                                 "or a system file, not single keys")
            # a host's own recording (`nodes`: that host's): only its nodes' traces and beats cross
            # from the other hosts' links to it; the hub's recording has theirs. The hub's own
            # recording with `nodes` (a host keeps its traces home): every node's heartbeats still
            self.keys = trace_keys(self.system, None if nodes is None else list(nodes),
                                   every_beat=bool(self.run and self.run.get("hub")))
        # trace-sourced: node paths whose outputs their own traces record (the system file's
        # nodes, every node seen on @trace) and every key a node published an output on
        self._nodes: set[str] = set() if self.declaration is None else set(self.declaration.nodes)
        self._output_keys: set[str] = set()
        self._pack = msgpack.Packer(use_bin_type=True).pack  # the writer thread's alone
        self._unpack = functools.partial(msgpack.unpackb, raw=False, strict_map_key=False)
        self.output = Path(output)
        if max_size is not None and max_size <= 0:
            raise ValueError(f"max_size must be a positive number of bytes, got {max_size!r}")
        if max_duration is not None and not max_duration > 0:
            raise ValueError(f"max_duration must be a positive number of seconds, got {max_duration!r}")
        self.max_size, self.max_duration = max_size, max_duration
        self.split = max_size is not None or max_duration is not None
        # split: a numbered file's name that is taken is skipped, unless the recording at `output`
        # is being replaced (--force), numbered files included
        self.replace = replace
        self.files: list[Path] = []  # the files written so far (split: the members; else output)
        self._set_id = uuid.uuid4().hex
        self.connect, self.listen = list(connect), list(listen or ())
        self.flush_period, self.spec_timeout, self.query_specs = flush_period, spec_timeout, query_specs
        self.stats = {"received": 0, "written": 0, "gaps": 0, "missing": 0, "duplicates": 0, "malformed": 0, "flushes": 0}
        self._stopping = threading.Event()
        self.fifo_capacity = fifo_capacity
        # `iotad record` runs as its own process and sets this: see `yield_cpu`. Off for a
        # recorder inside another program, whose threads are not ours to slow down.
        self.background = background
        self._session: Any = None
        self._subscribers: list = []
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self.specs: dict[str, dict] = {}
        self._asked: set[str] = set()
        self._schema_cache: dict[str, dict] = {}

    # ------------------------------------------------------------------ life cycle
    def start(self, keep_waiting: Callable[[], bool] | None = None) -> "Recorder":
        """Open the file, join zenoh, subscribe. With `connect` and no `listen`, while no hub
        answers there: `keep_waiting()` is asked about once a second whether to try again
        (default: fail at once, with zenoh's error)."""
        self.started_ns = wall_ns()
        self._open_file()
        try:
            if self.connect and not self.listen:
                # A client of the hub: the hub relays a node's samples to it from the node's first
                # put. A peer hears a new node only once gossip has linked the two directly, and
                # would miss what a (re)started node says first: its start record.
                self._session = self._open_client(keep_waiting)
            else:
                # a peer retries its `connect` in the background: every 100 ms too, not zenoh's
                # 1 s doubling to 4 s, which left a recorder started a few seconds before its hub
                # (a loaded machine) unlinked for the first seconds of the run it was to record
                self._session = open_session(self.listen or DEFAULT_LISTEN, self.connect,
                                             extra=CONNECT_RETRY if self.connect else None)
            # Samples wait in zenoh's own (Rust) FIFO until the writer thread takes them: no
            # Python callback on zenoh's threads, no GIL hand-off per sample. A full FIFO makes
            # zenoh push back on the senders (BLOCK) rather than lose.
            for key in self.keys:
                self._subscribers.append(self._session.declare_subscriber(
                    key, zenoh.handlers.FifoChannel(self.fifo_capacity)))
            self._thread = threading.Thread(target=self._run, name="iotad-recorder", daemon=True)
            self._thread.start()
            if self.background:
                self.priority = yield_cpu()  # after zenoh and the writer have started their threads
        except BaseException:
            self._close_session()
            self.sink.finish()  # a whole (empty) recording, and no open file left behind
            raise
        return self

    def _open_client(self, keep_waiting: Callable[[], bool] | None):
        # zenoh retries within each attempt (CONNECT_RETRY)
        while True:
            # Credentials are read as an attempt begins. A hub that `iotad run` guards lets no
            # one in without them, and the run writes them only as it starts: until they are
            # there, short attempts, so that the recorder is in before the nodes start (with 1 s
            # it came in after them, and a recording without the nodes' starts cannot be checked)
            timeout = 1.0 if for_endpoints(self.connect) is not None else 0.2
            try:
                return open_session((), self.connect, mode="client", connect_timeout=timeout, extra=CONNECT_RETRY)
            except zenoh.ZError:
                if keep_waiting is None or not keep_waiting():
                    raise

    def stop(self) -> dict:
        """Stop receiving, write what is queued, ask missing specs, and finish the file."""
        try:
            if self._thread is not None:
                self._stopping.set()  # the writer empties the FIFOs, then returns
                self._thread.join()
                self._thread = None
            for subscriber in self._subscribers:
                subscriber.undeclare()
            self._subscribers.clear()
            if self._error is not None:
                raise self._error
            self._ask_missing_specs()
            self._finish_file()
        finally:
            self._close_session()
        return self.stats

    # ------------------------------------------------------------------ files
    def _info(self) -> dict:
        info = {"format": FORMAT, "system": self.system or "", "keys": self.keys, "started_ns": self.started_ns,
                "source": "traces" if self.from_traces else "direct",
                "clock": "real", "writer": "iotad record",
                "time_unit": self._system_time_unit()}
        if self.run is not None:
            info["run"] = self.run
        if self.split:
            info["split"] = {"set": self._set_id, "index": len(self.files), "set_file": self.output.name,
                             "max_size": self.max_size, "max_duration": self.max_duration}
        return info

    def _open_file(self) -> None:
        """Begin the recording's (next) file, whole on its own: metadata, system file, the specs
        known so far. Split: name it in the set file first, so that a reader finds every member."""
        info = self._info()
        path = self.output
        if self.split:
            path = continuation_path(self.output, len(self.files))
            if not self.replace:  # never over another file: the set file names its members
                path = unused_recording_path(path, claim=True)
            write_set_file(self.output, self._set_id, [p.name for p in self.files] + [path.name],
                           dict(info, split={"set": self._set_id, "set_file": self.output.name}))
        self.sink = McapSink(path)
        self.files.append(path)
        self._file_opened = time.monotonic()
        self.sink.add_metadata("iotad.recording", info)
        if self.system_text is not None:
            self.sink.attach("system.toml", "application/toml", self.system_text.encode())
        for spec_path, spec in self.specs.items():
            self.sink.add_spec(spec_path, spec)
        self.sink.flush()

    def _finish_file(self) -> None:
        self.sink.add_metadata("iotad.gaps", {"count": self.stats["gaps"], "missing": self.stats["missing"]})
        self.sink.add_metadata("iotad.stats", dict(self.stats, stopped_ns=wall_ns(), files=len(self.files)))
        self.sink.finish()

    def _split_due(self, now: float, messages: int) -> bool:
        """Whether the file in progress has reached --max-size or --max-duration (and holds
        messages: a file is never split off empty)."""
        if not self.split or not messages:
            return False
        if self.max_size is not None and self.sink.size() >= self.max_size:
            return True
        return self.max_duration is not None and now - self._file_opened >= self.max_duration

    def _next_file(self) -> None:
        self._finish_file()
        self._open_file()

    @property
    def failed(self) -> BaseException | None:
        """What ended the writer thread early (a full disk...), or None while it records."""
        return self._error

    def _close_session(self) -> None:
        if self._session is not None:
            from iotad.node_host.session_close import close_session

            close_session(self._session)  # the file is finished by then; a cut-off host is not waited for
            self._session = None

    def _system_time_unit(self) -> float:
        return 1.0 if self.declaration is None else self.declaration.time_unit

    # ------------------------------------------------------------------ the writer thread
    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # noqa: BLE001 - reported by stop()
            self._error = exc

    def _loop(self) -> None:
        sink, stats = self.sink, self.stats
        receivers = [subscriber.handler.try_recv for subscriber in self._subscribers]
        ids: dict[str, int] = {}  # key -> channel id in the file in progress
        last: dict[str, tuple[int, int]] = {}
        # per @trace key: the `seq` its next burst should have (the last one's + its length)
        following: dict[str, int] = {}
        processes: dict[str, list] = {}  # per @trace key: the process its last burst named
        unpack_attachment = msgpack.unpackb
        write = sink.fast_writer()  # one per sink: it sets sink.write_pair and sink.commit
        burst = functools.partial(self._burst, write, sink.write_pair)
        # log times on the clock that origins are in (the same as time.time_ns but in a drill of a
        # host whose clock is wrong): a host's recording is moved onto the hub's by its offset
        now_ns, monotonic_ns = wall_ns, time.monotonic_ns
        period_ns = int(self.flush_period * 1e9)
        next_flush = monotonic_ns() + period_ns
        received = written = file_start = 0
        stopping = self._stopping.is_set
        quiet_since = stop_at = 0
        while True:
            idle = True
            for receive in receivers:
                for _ in range(4096):  # then the next key expression, and a flush check
                    sample = receive()
                    if sample is None:
                        break
                    idle = False
                    receipt_ns = now_ns()
                    key = str(sample.key_expr)
                    received += 1
                    channel_id = ids.get(key)
                    if channel_id is None:
                        channel_id = ids[key] = self._new_channel(key)
                    sequence, publish_ns = 0, receipt_ns
                    attachment = sample.attachment
                    if attachment is not None:
                        try:
                            fields = unpack_attachment(attachment.to_bytes())
                            sequence, publish_ns = fields[0], fields[1]
                        except Exception:  # noqa: BLE001 - a foreign publisher's attachment
                            fields, sequence, publish_ns = (), 0, receipt_ns
                        # a @trace burst names its process (pid, started_ns): a restart unheard
                        # (its host cut off) numbers from 0 again, with or without a jump
                        process = fields[2:4] if len(fields) > 3 else None
                        previous = last.get(key)
                        if previous is not None:
                            if sequence == previous[0] and publish_ns == previous[1]:
                                stats["duplicates"] += 1  # one sample through two overlapping key expressions
                                continue
                            expected = following.get(key, previous[0] + 1)
                            known = processes.get(key)
                            if process is not None and known is not None and process != known:
                                if sequence > 0:  # its start record is among what was not heard
                                    self._restarted(key, expected, sequence, process, receipt_ns)
                            elif sequence > expected:
                                self._gap(key, expected, sequence, receipt_ns)
                        if process is not None:
                            processes[key] = process
                        last[key] = (sequence, publish_ns)
                    data = sample.payload.to_bytes()
                    if key.endswith(_TRACE):
                        # a burst of events (or one event, the old form): one message per event
                        count, n = burst(key, channel_id, data, receipt_ns, publish_ns, sequence, ids, last)
                        following[key] = sequence + n if attachment is not None else _NEVER
                        written += count
                        if monotonic_ns() >= next_flush:
                            break  # a busy stream must flush on time too
                        continue
                    if key.endswith(_MAPS) and not self._is_map(key, sequence, data, receipt_ns):
                        continue  # recorded as malformed: readers of @launcher and @heartbeat take maps
                    write(channel_id, receipt_ns, publish_ns, sequence, data)
                    written += 1
                    if not (received & 255) and monotonic_ns() >= next_flush:
                        break  # a busy stream must flush on time too
            sink.commit()  # into the chunk in progress, at most 4096 samples a key expression
            now = monotonic_ns()
            if now >= next_flush:
                sink.flush()
                stats["flushes"] += 1
                next_flush = now + period_ns
                stats["received"], stats["written"] = received, written
                if self._split_due(now / 1e9, written - file_start):
                    self._next_file()
                    sink, file_start = self.sink, written
                    ids.clear()  # channel ids are per file: each one registers its channels anew
                    write = sink.fast_writer()
                    burst = functools.partial(self._burst, write, sink.write_pair)
            if idle:
                if stopping():
                    # what the senders already sent may still be on its way: stop only after
                    # 100 ms with nothing new (or 5 s after the stop request, whatever comes)
                    quiet_since = quiet_since or now
                    stop_at = stop_at or now + 5_000_000_000
                    if now - quiet_since >= 100_000_000 or now >= stop_at:
                        break
                time.sleep(0.002)  # idle: poll gently (the FIFOs hold what comes meanwhile)
            else:
                quiet_since = 0
        stats["received"], stats["written"] = received, written

    def _burst(self, write: Callable, write_pair: Callable, key: str, channel_id: int, data: bytes,
               receipt_ns: int, publish_ns: int, sequence: int, ids: dict[str, int],
               last: dict[str, tuple[int, int]]) -> tuple[int, int]:
        """One `@trace` sample: write each of its events as one message on `key` (sequence: the
        burst's `seq` plus the event's place in it, as if each had come alone) and, trace-sourced,
        the message each output or input event describes. A payload that is no event and no
        burst, or an element that is no event, is a recorded problem (`MALFORMED_TOPIC`), never
        an error. Returns (messages written, events the burst held: its length in `seq`)."""
        value = self._decoded(key, sequence, data, receipt_ns)
        if value is _UNDECODABLE:
            return 0, _NEVER - sequence
        if value.__class__ is dict:
            events, single = (value,), True
        elif value.__class__ is list:
            events, single = value, False
        else:
            self._malformed(key, sequence, f"a {type(value).__name__}, neither an event dict nor a burst (list)",
                            data, receipt_ns)
            return 0, _NEVER - sequence
        pack, derive, output_keys, traced = self._pack, self.from_traces, self._output_keys, self._traced
        written = 0
        for position, event in enumerate(events):
            seq = sequence + position
            if event.__class__ is not dict:
                self._malformed(key, seq, f"element {position} of the burst is a {type(event).__name__}, "
                                f"not an event dict", pack(event), receipt_ns)
                continue
            problem = trace_event_problem(event)
            if problem:  # on @trace, where every reader takes it for an event: a recorded problem
                self._malformed(key, seq, f"element {position} of the burst is no trace event: {problem}",
                                pack(event), receipt_ns)
                continue
            event_data = data if single else pack(event)
            kind = event.get("kind")
            if not derive or (kind != "output" and kind != "input"):
                write(channel_id, receipt_ns, publish_ns, seq, event_data)
                written += 1
                if derive and kind == "violation" and "seq" in event:
                    self._refused(key, event, last, receipt_ns)
                continue
            # an output event of a node host (the common case) is written with its message in
            # one go; the rest, and anything unexpected, in `_traced`
            out_key, out_seq, out_ns = event.get("key"), event.get("seq"), event.get("send_ns")
            fast = (kind == "output" and out_key.__class__ is str and out_seq.__class__ is int
                    and out_ns.__class__ is int)
            if fast:
                if out_key not in output_keys:
                    output_keys.add(out_key)
                previous = last.get(out_key)
                if previous is not None:
                    if out_seq == previous[0] and out_ns == previous[1]:
                        fast = False  # a duplicate: _traced counts it
                    elif out_seq > previous[0] + 1:
                        self._gap(out_key, previous[0] + 1, out_seq, receipt_ns)
            if fast:
                last[out_key] = (out_seq, out_ns)
                out_id = ids.get(out_key)
                if out_id is None:
                    out_id = ids[out_key] = self._new_channel(out_key)
                write_pair(channel_id, receipt_ns, publish_ns, seq, event_data,
                           out_id, out_ns, out_seq, pack(event["value"]))
                written += 2
            else:
                write(channel_id, receipt_ns, publish_ns, seq, event_data)
                written += 1 + traced(key, event, receipt_ns, write, ids, last)
        return written, len(events)

    def _is_map(self, key: str, sequence: int, data: bytes, receipt_ns: int) -> bool:
        """Whether an `@launcher` or `@heartbeat` payload is a msgpack map; if not, it is recorded
        on `MALFORMED_TOPIC` (a rogue or broken publisher must not make the file unreadable)."""
        value = self._decoded(key, sequence, data, receipt_ns)
        if value is _UNDECODABLE:
            return False
        if value.__class__ is not dict:
            self._malformed(key, sequence, f"a {type(value).__name__}, not a map", data, receipt_ns)
            return False
        return True

    def _decoded(self, key: str, sequence: int, data: bytes, receipt_ns: int) -> Any:
        """The msgpack value of a payload, or `_UNDECODABLE` (recorded on `MALFORMED_TOPIC`)."""
        try:
            return self._unpack(data)
        except Exception as exc:  # noqa: BLE001 - msgpack raises several unrelated types
            detail = str(exc) or f"starts {data[:16].hex(' ')}"  # some msgpack errors say nothing
            self._malformed(key, sequence, f"undecodable msgpack ({len(data)} bytes): {type(exc).__name__}: {detail}",
                            data, receipt_ns)
            return _UNDECODABLE

    def _malformed(self, key: str, sequence: int, message: str, data: bytes, receipt_ns: int) -> None:
        """Record what could not be read as trace events: on `MALFORMED_TOPIC` (key, seq, why, and
        the bytes themselves, up to 4 KiB), counted in the stats; the rest of the stream goes on."""
        self.stats["malformed"] += 1
        channel_id = self.sink.channel(MALFORMED_TOPIC, "iotad.malformed", schema_for_topic(MALFORMED_TOPIC, {}, {})[1])
        self.sink.write(channel_id, receipt_ns, receipt_ns, self.stats["malformed"] - 1,
                        packb({"key": key, "seq": sequence, "message": message, "data": bytes(data[:4096])}))

    def _traced(self, trace_key: str, event: Any, receipt_ns: int, write: Callable, ids: dict[str, int],
                last: dict[str, tuple[int, int]]) -> int:
        """Trace-sourced: write the message that an output or input event (decoded) on `trace_key`
        describes (on its key, publish time and sequence from the sender), unless another node's
        output records it. Returns how many messages were written (0 or 1)."""
        key = event.get("key") if isinstance(event, dict) else None
        if not isinstance(key, str):
            return 0  # a node host older than these fields: its trace holds its events still
        if event.get("kind") == "output":
            self._output_keys.add(key)
        elif key.startswith(CAN_KEY_PREFIX) or not self._unexplained(key, trace_key):
            # a CAN frame a station received (`can/<bus>`, no zenoh key): the receiver's trace
            # holds it and the bus log the frame itself; a topic of its own would hold it once
            # per receiving station, with nothing saying which
            return 0
        sequence, publish_ns = event.get("seq"), event.get("send_ns")
        if not (isinstance(sequence, int) and isinstance(publish_ns, int)):
            sequence, publish_ns = 0, receipt_ns  # an input from a publisher without the attachment
        else:
            previous = last.get(key)
            if previous is not None:
                if sequence == previous[0] and publish_ns == previous[1]:
                    self.stats["duplicates"] += 1  # one injected message that two nodes received
                    return 0
                if sequence > previous[0] + 1:
                    self._gap(key, previous[0] + 1, sequence, receipt_ns)
            last[key] = (sequence, publish_ns)
        channel_id = ids.get(key)
        if channel_id is None:
            channel_id = ids[key] = self._new_channel(key)
        write(channel_id, receipt_ns, publish_ns, sequence, self._pack(event.get("value")))
        return 1

    def _refused(self, trace_key: str, event: dict, last: dict[str, tuple[int, int]], receipt_ns: int) -> None:
        """Trace-sourced: an input from outside the system that its receiver refused (its
        violation carries the key and the sender's seq): no message to write, since its value
        was not taken, but a message seen, so the next one from that sender is no gap."""
        key, sequence, publish_ns = event.get("key"), event.get("seq"), event.get("send_ns")
        if not (isinstance(key, str) and isinstance(sequence, int) and isinstance(publish_ns, int)):
            return
        if not self._unexplained(key, trace_key):
            return  # a node's output: its own trace counts its sequence
        previous = last.get(key)
        if previous is not None and sequence > previous[0] + 1:
            self._gap(key, previous[0] + 1, sequence, receipt_ns)
        if previous is None or sequence > previous[0]:
            last[key] = (sequence, publish_ns)

    def _unexplained(self, key: str, trace_key: str) -> bool:
        """Whether an input that arrived on `key` (seen on `trace_key`) is no node's output: a
        key of the receiving node itself that it never published on (`iotad pub` into its input),
        or a key of a node that neither the system file names nor has a trace."""
        parsed = wire.parse_key(key)
        if parsed is None:
            return True
        receiver = trace_key[:-len(_TRACE)].split("/", 2)[2]
        if parsed[1] == receiver:
            return key not in self._output_keys
        return parsed[1] not in self._nodes

    def _gap(self, key: str, expected: int, got: int, receipt_ns: int) -> None:
        missing = got - expected
        self.stats["gaps"] += 1
        self.stats["missing"] += missing
        channel_id = self.sink.channel(GAP_TOPIC, "iotad.gap", schema_for_topic(GAP_TOPIC, {}, {})[1])
        self.sink.write(channel_id, receipt_ns, receipt_ns, self.stats["gaps"] - 1,
                        packb({"key": key, "expected": expected, "got": got, "missing": missing}))

    def _restarted(self, key: str, expected: int, got: int, process: list, receipt_ns: int) -> None:
        """A new process of a node whose first `got` trace events (its start record first) were not
        heard: noted with the gaps (`wire.restart_note`), so that a reader judges it afresh."""
        self.stats["gaps"] += 1
        self.stats["missing"] += got
        channel_id = self.sink.channel(GAP_TOPIC, "iotad.gap", schema_for_topic(GAP_TOPIC, {}, {})[1])
        self.sink.write(channel_id, receipt_ns, receipt_ns, self.stats["gaps"] - 1,
                        packb(wire.restart_note(key, expected, got, (int(process[0]), int(process[1])))))

    def _new_channel(self, key: str) -> int:
        parsed = wire.parse_key(key)
        if parsed is not None and parsed[2] == wire.TRACE:
            self._nodes.add(parsed[1])
        if parsed is not None and parsed[1] and self.query_specs:
            self._ask_spec(parsed[0], parsed[1])
        name, schema = schema_for_topic(key, self.specs, self._schema_cache)
        return self.sink.channel(key, name, schema)

    # ------------------------------------------------------------------ specs
    def _ask_spec(self, system: str, path: str) -> None:
        """Ask a node for its spec once (a node answers on `<node>/@spec`); store the answer."""
        if (system, path) in self._asked or path in self.specs:
            return
        self._asked.add((system, path))
        try:
            replies = self._session.get(wire.node_key(system, path, wire.SPEC), timeout=self.spec_timeout)
            for reply in replies:
                sample = reply.ok
                if sample is None:
                    continue
                spec = msgpack.unpackb(sample.payload.to_bytes(), raw=False, strict_map_key=False)
                if isinstance(spec, dict):
                    spec.setdefault("path", path)
                    self.specs[path] = spec
                    self._schema_cache[path] = channel_schemas(spec)
                    self.sink.add_spec(path, spec)
                    break
        except Exception:  # noqa: BLE001 - a node without a spec is still recorded
            pass

    def _ask_missing_specs(self) -> None:
        if not self.query_specs or self._session is None:
            return
        seen = set()
        for topic in self.sink.channels:
            parsed = wire.parse_key(topic)
            if parsed and parsed[1] and topic.endswith(_TRACE):
                seen.add((parsed[0], parsed[1]))
        for system, path in sorted(seen):
            if path not in self.specs:
                self._asked.discard((system, path))
                self._ask_spec(system, path)


def describe(stats: dict) -> str:
    return json.dumps(stats)
