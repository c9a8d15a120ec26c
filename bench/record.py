"""Recording throughput and cost (prints figures and goal status; asserts nothing).

    .venv/bin/python bench/record.py [--publishers 4] [--messages 100000] [--samples 2000]

1. raw: the `mcap` Writer alone, in this process, writing messages like the recorder's (zstd
   chunks, a flush every 50 ms): the ceiling of any Python recorder. Then `McapSink` the same
   way, through its batch writer (the recorder's hot path, which uses the mcap Writer's private
   fields: iotad/recording/mcap_batch_writer.py) and through the Writer's public API, in turn:
   what the private access is worth.
2. record: an `iotad record` process and --publishers publisher processes (subprocess, never
   fork), each publishing --messages events as fast as it can with BLOCK congestion control.
   --mode traces (default; what `iotad run` uses): each event is an output event on the
   publisher's `@trace` key carrying key, seq and send_ns, sent as a node host sends its trace
   (bursts of 64 events, one zenoh sample each, as under a flood of inputs), and the
   recorder (`--from-traces`) writes the trace event and the output message it describes;
   --mode direct: the event goes on the output key with the `[sequence, send_time_ns]`
   attachment and the recorder subscribes to every key. Counted from the file afterwards: output
   messages per second over the recorder's receive span, and loss (every sequence number of every
   publisher must be on its output key).
3. latency: round trip ping -> pong process -> ping (zenoh, loopback), p50/p99, alternately
   without and with an `iotad record` process (--rounds times); the cost is the median over the
   alternations. In direct mode every message of the round trip also wakes the recorder; in traces
   mode the pong process also sends its input and output events on its `@trace` in bursts every
   20 ms, as a node host does (bench/latency.py measures it on a real node).
Goals: >= 100,000 events/s with zero loss; recording adds <= 10% to the round-trip p50.
"""
from __future__ import annotations

import argparse
import os
import queue
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402
from importlib.metadata import version  # noqa: E402

from iotad.node_host import wire  # noqa: E402
from iotad.node_host.transport import free_port, open_session  # noqa: E402

GOAL_RATE = 100_000
GOAL_LATENCY_COST = 0.10

PUBLISHER = r"""
import sys, time
sys.path.insert(0, {root!r})
import zenoh
from iotad.node_host import wire
from iotad.node_host.transport import open_session
endpoint, index, count, mode = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
session = open_session(connect=[endpoint])
try:
    key = f"iota/bench/p{{index}}/out"
    pub = session.declare_publisher(key if mode == "direct" else f"iota/bench/p{{index}}/@trace",
                                    congestion_control=zenoh.CongestionControl.BLOCK)
    deadline = time.monotonic() + 20
    while not pub.matching_status.matching and time.monotonic() < deadline:
        time.sleep(0.01)
    sys.stdout.write("ready\n"); sys.stdout.flush()
    sys.stdin.readline()  # go
    payload = wire.encode({{"t": 0.0, "iota": "p", "action": "out", "index": None, "kind": "output", "value": 1.5}})
    put, attach, now, encode = pub.put, wire.encode_attachment, time.time_ns, wire.encode
    if mode == "direct":
        for seq in range(count):
            put(payload, attachment=attach(seq, now()))
    else:
        # as a node host: each output event notes its key, seq and send_ns; the trace goes out in
        # bursts of TRACE_BATCH events, one sample each (attachment: seq of the burst's first event)
        from iotad.node_host.host_clock import HostClock
        batch, buffer, first = HostClock.TRACE_BATCH, [], 0
        for seq in range(count):
            buffer.append({{"t": 0.0, "iota": "p", "action": "out", "index": None, "kind": "output", "value": 1.5,
                           "key": key, "seq": seq, "send_ns": now()}})
            if len(buffer) >= batch or seq == count - 1:
                put(wire.encode_burst(buffer), attachment=attach(first, now()))
                first += len(buffer)
                buffer = []
    sys.stdout.write("done\n"); sys.stdout.flush()
    sys.stdin.readline()
finally:
    session.close()
"""

PONG = r"""
import sys, threading, time
sys.path.insert(0, {root!r})
import zenoh
from iotad.node_host import wire
from iotad.node_host.transport import open_session
session = open_session(connect=[sys.argv[1]])
traced = sys.argv[2] == "traces"
stop, flusher = threading.Event(), None
try:
    pub = session.declare_publisher("iota/bench/pong/out", express=True, congestion_control=zenoh.CongestionControl.BLOCK)
    trace = session.declare_publisher("iota/bench/pong/@trace", congestion_control=zenoh.CongestionControl.BLOCK,
                                      priority=zenoh.Priority.DATA_LOW)
    buffer, seqs = [], [0, 0]
    def answer(sample):
        attachment = sample.attachment.to_bytes() if sample.attachment is not None else None
        send_ns = time.time_ns()
        pub.put(sample.payload.to_bytes(), attachment=wire.encode_attachment(seqs[0], send_ns))
        if traced:  # what a node host's trace holds: the input (sender's attachment) and the output
            seq, sent = wire.decode_attachment(attachment) or (0, 0)
            value = wire.decode(sample.payload.to_bytes())
            buffer.append({{"t": 0.0, "iota": "pong", "action": "inp", "index": None, "kind": "input", "value": value,
                           "key": "iota/bench/ping/out", "seq": seq, "send_ns": sent}})
            buffer.append({{"t": 0.0, "iota": "pong", "action": "out", "index": None, "kind": "output", "value": value,
                           "key": "iota/bench/pong/out", "seq": seqs[0], "send_ns": send_ns}})
        seqs[0] += 1
    def flush():  # every 20 ms, as a node host's trace_period, until the stop
        while not stop.wait(0.02):
            events, buffer[:] = list(buffer), []
            if events:  # one sample per burst, as a node host
                trace.put(wire.encode_burst(events), attachment=wire.encode_attachment(seqs[1]))
                seqs[1] += len(events)
    flusher = threading.Thread(target=flush, daemon=True)
    flusher.start()
    sub = session.declare_subscriber("iota/bench/ping/out", answer)
    sys.stdout.write("ready\n"); sys.stdout.flush()
    sys.stdin.readline()
    sub.undeclare()  # no more answers, then no more trace
finally:
    stop.set()  # the flush thread ends before the session it puts on closes
    if flusher is not None:
        flusher.join()
    session.close()
"""


def raw_writer(count: int) -> float:
    """Messages per second of the bare mcap Writer (with the recorder's 50 ms flushes)."""
    from mcap.writer import Writer
    payload = wire.encode({"t": 0.0, "iota": "p", "action": "out", "index": None, "kind": "output", "value": 1.5})
    with tempfile.TemporaryFile() as stream:
        writer = Writer(stream, chunk_size=4 * 1024 * 1024)
        writer.start()
        schema = writer.register_schema("x", "jsonschema", b"{}")
        channels = [writer.register_channel(f"iota/bench/p{k}/out", "msgpack", schema) for k in range(4)]
        start = time.perf_counter()
        next_flush = time.monotonic() + 0.05
        for seq in range(count):
            now = time.time_ns()
            writer.add_message(channels[seq & 3], now, payload, now, seq)
            if time.monotonic() >= next_flush:
                writer.flush()
                next_flush = time.monotonic() + 0.05
        writer.finish()
        return count / (time.perf_counter() - start)


def sink_writes(count: int, fast: bool) -> float:
    """Messages per second through `McapSink`: its batch writer (`fast`, committed every 4096
    messages as the recorder does) or its public-API `write`; 50 ms flushes as in `raw_writer`."""
    from iotad.recording.mcap_sink import McapSink
    payload = wire.encode({"t": 0.0, "iota": "p", "action": "out", "index": None, "kind": "output", "value": 1.5})
    with tempfile.TemporaryDirectory() as folder:
        sink = McapSink(Path(folder) / "sink.mcap")
        channels = [sink.channel(f"iota/bench/p{k}/out", "x", {}) for k in range(4)]
        write = sink.fast_writer() if fast else sink.write
        start = time.perf_counter()
        next_flush = time.monotonic() + 0.05
        for seq in range(count):
            now = time.time_ns()
            write(channels[seq & 3], now, now, seq, payload)
            if seq & 4095 == 4095:
                sink.commit()
                if time.monotonic() >= next_flush:
                    sink.flush()
                    next_flush = time.monotonic() + 0.05
        sink.finish()
        return count / (time.perf_counter() - start)


class Recorder:
    def __init__(self, output: Path, keys: list[str], connect: str | None = None, mode: str = "traces"):
        self.port = free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        ready = output.with_suffix(".ready")
        argv = [sys.executable, "-m", "iotad.cli", "record", *keys, "-o", str(output), "--quiet",
                "--listen", self.endpoint, "--ready-file", str(ready)]
        if mode == "traces":
            argv.append("--from-traces")
        if connect:
            argv += ["--connect", connect]
        self.proc = subprocess.Popen(argv, cwd=ROOT)
        deadline = time.monotonic() + 20
        while not ready.exists():
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise SystemExit("the recorder did not start")
            time.sleep(0.02)

    def stop(self) -> None:
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(120)


def spawn(script: str, *args: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", script.format(root=str(ROOT)), *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    if proc.stdout.readline().strip() != "ready":
        raise SystemExit("a helper process did not start")
    return proc


def throughput(publishers: int, messages: int, folder: Path, mode: str) -> dict:
    from iotad.recording.mcap_reader import read_recording
    output = folder / "throughput.mcap"
    recorder = Recorder(output, ["iota/bench/**"], mode=mode)
    procs = []
    try:
        procs = [spawn(PUBLISHER, recorder.endpoint, str(k), str(messages), mode) for k in range(publishers)]
        for proc in procs:
            proc.stdin.write("go\n")
            proc.stdin.flush()
        for proc in procs:
            if proc.stdout.readline().strip() != "done":
                raise SystemExit("a publisher failed")
        # The recorder's clean stop drains what is still on its way (until 100 ms of quiet).
    finally:
        recorder.stop()
        for proc in procs:
            try:
                proc.stdin.write("bye\n")
                proc.stdin.flush()
            except BrokenPipeError:
                pass
            proc.wait(20)
    recording = read_recording(output)
    per_key: dict[str, set] = {}
    times = []
    for message in recording.messages:
        if message.topic.startswith("iota/bench/p") and message.topic.endswith("/out"):
            per_key.setdefault(message.topic, set()).add(message.sequence)
            times.append(message.log_time)
    got = sum(len(s) for s in per_key.values())
    expected = publishers * messages
    span = (max(times) - min(times)) / 1e9 if times else float("inf")
    complete = all(per_key.get(f"iota/bench/p{k}/out", set()) == set(range(messages)) for k in range(publishers))
    return {"events": got, "expected": expected, "lost": expected - got, "zero_loss": complete and got == expected,
            "seconds": span, "rate": got / span if span > 0 else 0.0, "gaps": len(recording.gaps()),
            "size_mb": output.stat().st_size / 1e6}


def round_trips(samples: int, recorded: bool, folder: Path, mode: str) -> list[float]:
    hub_endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = open_session([hub_endpoint])
    recorder = pong = None
    try:
        if recorded:
            recorder = Recorder(folder / f"latency-{time.time_ns()}.mcap", ["iota/bench/**"], connect=hub_endpoint,
                                mode=mode)
        pong = spawn(PONG, hub_endpoint, mode)
        replies: queue.SimpleQueue = queue.SimpleQueue()
        session.declare_subscriber("iota/bench/pong/out", lambda s: replies.put(time.perf_counter()))
        ping = session.declare_publisher("iota/bench/ping/out", express=True,
                                         congestion_control=zenoh.CongestionControl.BLOCK)
        deadline = time.monotonic() + 10
        while not ping.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        payload = wire.encode({"w": 1.0, "k": 0.5})
        answered, deadline = 0, time.monotonic() + 30
        while answered < 200:  # warm up: routes, recorder channels, caches
            if time.monotonic() > deadline:
                raise SystemExit("the pong process does not answer")
            ping.put(payload, attachment=wire.encode_attachment(0))
            try:  # the pong may not know our subscriber yet: its first answers can go nowhere
                replies.get(timeout=0.5)
                answered += 1
            except queue.Empty:
                pass
        time.sleep(0.1)
        while not replies.empty():
            replies.get()  # a late answer must not end a measured round trip
        out = []
        for seq in range(samples):
            start = time.perf_counter()
            ping.put(payload, attachment=wire.encode_attachment(seq))
            out.append(replies.get(timeout=5) - start)
            time.sleep(0.0005)
        return out
    finally:
        if pong is not None:
            pong.stdin.write("bye\n")
            pong.stdin.flush()
            pong.wait(20)
        if recorder is not None:
            recorder.stop()
        session.close()


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--publishers", type=int, default=4)
    parser.add_argument("--messages", type=int, default=100_000, help="per publisher")
    parser.add_argument("--samples", type=int, default=2000, help="round trips per latency run")
    parser.add_argument("--rounds", type=int, default=3, help="latency runs with the recorder, each between two without")
    parser.add_argument("--mode", choices=["traces", "direct"], default="traces",
                        help="traces: the recorder as 'iotad run' starts it (--from-traces); direct: every key")
    args = parser.parse_args()
    print(f"bench/record.py on {os.cpu_count()} CPUs, python {sys.version.split()[0]}, zenoh {version('eclipse-zenoh')}, "
          f"recorder mode {args.mode}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        raw = raw_writer(200_000)
        print(f"raw mcap Writer:   {raw:>10,.0f} msgs/s (in-process, zstd, 50 ms flushes)")
        # alternated, best of three each: the machine's load drifts between runs
        rates = [(sink_writes(200_000, True), sink_writes(200_000, False)) for _ in range(3)]
        fast, public = max(r[0] for r in rates), max(r[1] for r in rates)
        print(f"McapSink writes:   {fast:>10,.0f} msgs/s batch writer (private fields), {public:,.0f} msgs/s "
              f"public API: {fast / public:.1f}x (mcap {version('mcap')})")
        result = throughput(args.publishers, args.messages, folder, args.mode)
        print(f"iotad record:      {result['rate']:>10,.0f} events/s from {args.publishers} publisher processes; "
              f"{result['events']:,}/{result['expected']:,} recorded, lost {result['lost']}, "
              f"{result['gaps']} gaps, {result['seconds']:.2f} s, {result['size_mb']:.1f} MB")
        # Alternate runs without and with the recorder: the machine's load drifts (other processes),
        # and each cost is taken against the mean of the baselines just before and after it.
        bases = [round_trips(args.samples, False, folder, args.mode)]
        recorded = []
        for _ in range(args.rounds):
            recorded.append(round_trips(args.samples, True, folder, args.mode))
            bases.append(round_trips(args.samples, False, folder, args.mode))
    costs = []
    for k, with_recorder in enumerate(recorded):
        p50 = (statistics.median(bases[k]) + statistics.median(bases[k + 1])) / 2
        p50_rec = statistics.median(with_recorder)
        costs.append((p50_rec - p50) / p50)
        print(f"round trip p50:    {p50 * 1e6:8.0f} us without recorder, {p50_rec * 1e6:8.0f} us with "
              f"({costs[-1]:+.1%}); p99 {quantile(bases[k], 0.99) * 1e6:.0f} / "
              f"{quantile(with_recorder, 0.99) * 1e6:.0f} us")
    cost = statistics.median(costs)
    print(f"recording cost on the round-trip p50 over {len(costs)} alternations: median {cost:+.1%}, "
          f"min {min(costs):+.1%}, max {max(costs):+.1%}")
    rate_ok = result["rate"] >= GOAL_RATE and result["zero_loss"]
    cost_ok = cost <= GOAL_LATENCY_COST
    print(f"goal >= {GOAL_RATE:,} events/s with zero loss: {'MET' if rate_ok else 'MISSED'}")
    print(f"goal recording adds <= {GOAL_LATENCY_COST:.0%} to p50: {'MET' if cost_ok else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
