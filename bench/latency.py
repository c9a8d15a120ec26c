"""Round-trip latency of the node host, against raw zenoh, in one run (prints figures, asserts nothing).

    .venv/bin/python bench/latency.py [--samples 2000] [--nodes 32]

1. raw: zenoh ping-pong between this process and a bare Python pong process;
2. echo: the same ping through an echo IOTA node process (input action -> output action); then
   again while an `iotad record` process records the system (unless --no-record), and once more
   without it: the recording cost is the p50 with it against the mean p50 of the runs around it.
   The recorder runs as `iotad run` starts it (--from-traces), or on every key (--record-mode direct);
3. figure2: a request -> mdl_command through the Figure 2 scheduler node process;
4. crowd: with --nodes echo node processes running, pings spread over all of them: p99, and each
   node's resident memory (VmRSS from /proc).
Every process is on loopback and connects to this process's hub session; all are stopped at exit.
"""
from __future__ import annotations

import argparse
import json
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

from iotad.node_host import wire  # noqa: E402
from iotad.node_host.transport import free_port, open_session  # noqa: E402

ECHO = f"{ROOT / 'examples' / 'echo.py'}:Echo"
SCHEDULER = f"{ROOT / 'examples' / 'scheduler.py'}:Scheduler"
GOALS = {"echo_overhead_p50_us": 100.0, "echo_p99_ms": 2.0, "crowd_p99_ms": 5.0, "crowd_rss_mb": 40.0,
         "echo_record_cost": 0.10}


def pong(endpoint: str) -> None:
    """The raw peer: answer every ping at once, nothing else."""
    session = open_session(["tcp/127.0.0.1:0"], [endpoint])
    try:
        publisher = session.declare_publisher("bench/pong", express=True,
                                              congestion_control=zenoh.CongestionControl.BLOCK)
        session.declare_subscriber("bench/ping", lambda sample: publisher.put(sample.payload.to_bytes()))
        session.declare_publisher("bench/pong_ready").put(b"")
        sys.stdin.read()  # until the bench closes our stdin
    finally:
        session.close()


class Bench:
    def __init__(self):
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.session = open_session([self.endpoint])
        self.replies: queue.SimpleQueue = queue.SimpleQueue()
        self.processes: list[subprocess.Popen] = []

    def close(self) -> None:
        for process in self.processes:
            if process.poll() is None:
                process.terminate()
        for process in self.processes:
            try:
                process.wait(5)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self.session.close()

    def listen(self, key: str) -> None:
        self.session.declare_subscriber(key, lambda sample: self.replies.put(sample.payload.to_bytes()))

    def wait_key(self, key: str, timeout: float = 60.0) -> None:
        seen: queue.SimpleQueue = queue.SimpleQueue()
        subscriber = self.session.declare_subscriber(key, lambda sample: seen.put(True))
        try:
            seen.get(timeout=timeout)
        finally:
            subscriber.undeclare()

    def start_node(self, system: str, path: str, ref: str, **extra) -> subprocess.Popen:
        config = {"system": system, "path": path, "source": {"kind": "python", "ref": ref},
                  "listen": ["tcp/127.0.0.1:0"], "connect": [self.endpoint], "heartbeat_period": 0.5, **extra}
        process = subprocess.Popen([sys.executable, "-m", "iotad.node_host", "--config-json", json.dumps(config)],
                                   cwd=ROOT)
        self.processes.append(process)
        return process

    def ping(self, publishers: list, payloads: list[bytes], samples: int, warmup: int = 200) -> list[float]:
        """Round trips in microseconds; one message in flight at a time."""
        rtts = []
        get = self.replies.get
        for k in range(warmup + samples):
            publisher = publishers[k % len(publishers)]
            payload = payloads[k % len(payloads)]
            start = time.perf_counter_ns()
            publisher.put(payload, attachment=wire.encode_attachment(k))
            get(timeout=5.0)
            if k >= warmup:
                rtts.append((time.perf_counter_ns() - start) / 1000.0)
        return rtts

    def publisher(self, key: str):
        return self.session.declare_publisher(key, express=True, congestion_control=zenoh.CongestionControl.BLOCK)


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def private_mb(pid: int) -> float:
    """Memory only this process holds (RSS less the pages of libzenoh/libpython shared by all)."""
    fields = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines()[1:]:
        name, value = line.split(":", 1)
        fields[name] = int(value.split()[0])
    return (fields.get("Private_Clean", 0) + fields.get("Private_Dirty", 0)) / 1024.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--nodes", type=int, default=32)
    parser.add_argument("--no-record", action="store_true", help="skip the echo-with-recorder rows")
    parser.add_argument("--record-mode", choices=["traces", "direct"], default="traces",
                        help="traces: the recorder as 'iotad run' starts it (--from-traces); direct: every key")
    parser.add_argument("--pong", metavar="ENDPOINT", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.pong:
        pong(args.pong)
        return 0

    bench = Bench()
    results: dict[str, list[float]] = {}
    try:
        # 1. raw zenoh
        raw = subprocess.Popen([sys.executable, __file__, "--pong", bench.endpoint], stdin=subprocess.PIPE)
        bench.processes.append(raw)
        bench.wait_key("bench/pong_ready")
        bench.listen("bench/pong")
        ping = bench.publisher("bench/ping")
        _wait_match(ping)
        results["raw"] = bench.ping([ping], [wire.encode(7)], args.samples)
        raw.stdin.close()

        # 2. echo IOTA node
        bench.start_node("bench", "echo", ECHO)
        bench.wait_key("iota/bench/echo/@heartbeat")
        bench.listen("iota/bench/echo/out")
        echo = bench.publisher("iota/bench/echo/inp")
        _wait_match(echo)
        results["echo"] = bench.ping([echo], [wire.encode(7)], args.samples)

        # 2b. the same echo while `iotad record` records the system (its input, output, @trace),
        # then once more without: the cost of recording, against the mean of the two baselines.
        if not args.no_record:
            with tempfile.TemporaryDirectory() as folder:
                recorder = start_recorder(bench.endpoint, Path(folder) / "echo.mcap", args.record_mode)
                try:
                    time.sleep(0.5)  # the recorder has asked the node for its @spec
                    results["echo+rec"] = bench.ping([echo], [wire.encode(7)], args.samples)
                finally:
                    recorder.send_signal(signal.SIGINT)
                    recorder.wait(60)
            results["echo again"] = bench.ping([echo], [wire.encode(7)], args.samples)

        # 3. Figure 2: req -> mdl_command. Each request outbids the last (priority k+1), so the
        # scheduler schedules it at once; switching times of 1 unit are 0.1 ms here.
        bench.start_node("bench", "sched", SCHEDULER, params={"N": 2, "T": 1.0}, time_unit=1e-4)
        bench.wait_key("iota/bench/sched/@heartbeat")
        bench.listen("iota/bench/sched/mdl_command")
        request = bench.publisher("iota/bench/sched/req/0")
        _wait_match(request)
        total = args.samples + 200
        requests = [wire.encode({"control": {"w": 0.5, "k": 1.0}, "epoch": 1e12, "timeout": 1e12, "priority": k + 1})
                    for k in range(total)]
        results["figure2"] = bench.ping([request], requests, args.samples)

        # 4. a crowd of echo nodes
        crowd = [bench.start_node("crowd", f"e{k}", ECHO) for k in range(args.nodes)]
        for k in range(args.nodes):
            bench.wait_key(f"iota/crowd/e{k}/@heartbeat", timeout=120)
        bench.listen("iota/crowd/*/out")
        publishers = [bench.publisher(f"iota/crowd/e{k}/inp") for k in range(args.nodes)]
        for publisher in publishers:
            _wait_match(publisher)
        results["crowd"] = bench.ping(publishers, [wire.encode(7)], args.samples)
        rss = [rss_mb(p.pid) for p in crowd]
        private = [private_mb(p.pid) for p in crowd]
    finally:
        bench.close()

    raw_p50 = statistics.median(results["raw"])
    print(f"round trips, {args.samples} samples each (microseconds):")
    print(f"{'':<10} {'p50':>8} {'p99':>8} {'max':>8}  {'p50/raw':>7} {'p99/raw':>7}")
    raw_p99 = quantile(results["raw"], 0.99)
    for name, rtts in results.items():
        p50, p99 = statistics.median(rtts), quantile(rtts, 0.99)
        label = name if name != "crowd" else f"crowd({args.nodes})"
        print(f"{label:<10} {p50:8.0f} {p99:8.0f} {max(rtts):8.0f}  {p50 / raw_p50:7.2f} {p99 / raw_p99:7.2f}")
    print(f"node RSS with {args.nodes} nodes (MB): min {min(rss):.1f} median {statistics.median(rss):.1f} "
          f"max {max(rss):.1f}; private (not shared with the other nodes): median "
          f"{statistics.median(private):.1f} max {max(private):.1f}")
    figures = {"echo_overhead_p50_us": statistics.median(results["echo"]) - raw_p50,
               "echo_p99_ms": quantile(results["echo"], 0.99) / 1000,
               "crowd_p99_ms": quantile(results["crowd"], 0.99) / 1000, "crowd_rss_mb": max(rss)}
    if "echo+rec" in results:
        baseline = (statistics.median(results["echo"]) + statistics.median(results["echo again"])) / 2
        figures["echo_record_cost"] = statistics.median(results["echo+rec"]) / baseline - 1
        print(f"recording cost ({args.record_mode}) on the echo round trip: p50 {statistics.median(results['echo+rec']):.0f} us with "
              f"`iotad record`, {baseline:.0f} us without (mean of the runs before and after): "
              f"{figures['echo_record_cost']:+.1%}")
    print("goals:")
    for name, limit in GOALS.items():
        if name not in figures:
            continue
        value = figures[name]
        print(f"  {name:<22} {value:9.3f} <= {limit:<6g} {'met' if value <= limit else 'MISSED'}")
    return 0


def start_recorder(hub: str, output: Path, mode: str = "traces") -> subprocess.Popen:
    ready = output.with_suffix(".ready")
    process = subprocess.Popen([sys.executable, "-m", "iotad.cli", "record", "iota/bench/**", "-o", str(output),
                                "--quiet", "--connect", hub, "--ready-file", str(ready),
                                *(["--from-traces"] if mode == "traces" else [])], cwd=ROOT)
    deadline = time.monotonic() + 30
    while not ready.exists():
        if process.poll() is not None or time.monotonic() > deadline:
            raise SystemExit("the recorder did not start")
        time.sleep(0.02)
    return process


def _wait_match(publisher, timeout: float = 10.0) -> None:
    """A put before the subscriber's declaration reached us would be lost."""
    end = time.monotonic() + timeout
    while not publisher.matching_status.matching:
        if time.monotonic() > end:
            raise SystemExit(f"no subscriber for {publisher.key_expr} after {timeout}s")
        time.sleep(0.01)


if __name__ == "__main__":
    sys.exit(main())
