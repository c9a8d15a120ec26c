"""What access control costs: the round trip through an echo node of a system run by `iotad run`,
with access control on (the default: the node and this pinger are authenticated clients of the
hub, every message crosses the hub's rules) against `--insecure` (peers meshed directly), in one
run, alternating on/off rounds. Prints figures and ratios; asserts nothing.

    .venv/bin/python bench/access_control.py [--samples 2000] [--rounds 2]
"""
from __future__ import annotations

import argparse
import queue
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402

from iotad.node_host import credentials, wire  # noqa: E402
from iotad.node_host.transport import free_port, open_session  # noqa: E402
from iotad.launcher.processes import interrupt_then_kill  # noqa: E402

SYSTEM = """
[system]
name = "aclbench"
external = ["echo.inp"]
[system.debug]
allow_pub = ["echo.inp"]          # the pinger writes the echo's input with the tools' credentials
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]
[[node]]
name = "echo"
python = "{root}/examples/echo.py:Echo"
"""


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def one_round(folder: Path, secure: bool, samples: int, warmup: int = 200) -> list[float]:
    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    system = folder / f"aclbench-{port}.toml"
    system.write_text(SYSTEM.format(port=port, root=ROOT))
    out = open(folder / f"run-{port}.out", "wb")
    argv = [sys.executable, "-m", "iotad", "run", str(system), "--no-record", "--plain",
            "--log-dir", str(folder / f"logs-{port}")] + ([] if secure else ["--insecure"])
    launcher = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True)
    session = None
    try:
        deadline = time.monotonic() + 30
        while b"echo: live" not in (folder / f"run-{port}.out").read_bytes():
            if time.monotonic() > deadline or launcher.poll() is not None:
                raise RuntimeError((folder / f"run-{port}.out").read_text()[-2000:])
            time.sleep(0.05)
        if secure:  # a client with the tools' credentials, as `iotad pub` would be
            session = open_session((), [hub], mode="client", connect_timeout=5.0,
                                   credentials=credentials.for_endpoints([hub]))
        else:       # a listening peer, meshed with the node as nodes are
            session = open_session(["tcp/127.0.0.1:0"], [hub], credentials=False)
        replies: queue.SimpleQueue = queue.SimpleQueue()
        session.declare_subscriber(wire.channel_key("aclbench", "echo", "out"), lambda s: replies.put(1))
        publisher = session.declare_publisher(wire.channel_key("aclbench", "echo", "inp"), express=True,
                                              congestion_control=zenoh.CongestionControl.BLOCK)
        deadline = time.monotonic() + 20
        while True:  # until the path works end to end
            publisher.put(wire.encode(0), attachment=wire.encode_attachment(0, time.time_ns()))
            try:
                replies.get(timeout=0.2)
                break
            except queue.Empty:
                if time.monotonic() > deadline:
                    raise RuntimeError("no echo") from None
        time.sleep(0.3)
        while not replies.empty():
            replies.get()
        rtts = []
        for k in range(warmup + samples):
            start = time.perf_counter_ns()
            publisher.put(wire.encode(k), attachment=wire.encode_attachment(k, time.time_ns()))
            replies.get(timeout=5.0)
            if k >= warmup:
                rtts.append((time.perf_counter_ns() - start) / 1000.0)
        return rtts
    finally:
        if session is not None:
            session.close()
        interrupt_then_kill(launcher, 20)
        out.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=2, help="on/off pairs, alternated")
    args = parser.parse_args()
    results: dict[bool, list[list[float]]] = {True: [], False: []}
    with tempfile.TemporaryDirectory(prefix="iotad-aclbench-") as folder:
        for _ in range(args.rounds):
            for secure in (False, True):
                results[secure].append(one_round(Path(folder), secure, args.samples))
    print(f"echo round trip through one node of an 'iotad run' system, {args.samples} samples x {args.rounds} rounds")
    print(f"{'':<26}{'p50 us':>10}{'p90 us':>10}{'p99 us':>10}")
    rows = {}
    for secure, label in ((False, "access control off"), (True, "access control on")):
        p50 = statistics.median(quantile(r, 0.5) for r in results[secure])
        p90 = statistics.median(quantile(r, 0.9) for r in results[secure])
        p99 = statistics.median(quantile(r, 0.99) for r in results[secure])
        rows[secure] = (p50, p90, p99)
        print(f"{label:<26}{p50:>10.0f}{p90:>10.0f}{p99:>10.0f}")
    print("on / off ratio            " + "".join(f"{on / off:>10.2f}" for on, off in zip(rows[True], rows[False])))
    print("(on: clients routed through the hub, which checks every message; off: peers meshed directly)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
