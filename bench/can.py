"""CAN benchmark, on the best CAN tier this host has (vcan, user-mode Linux, udp_multicast).

Baseline: the raw python-can round trip between two processes on the same bus (a frame out,
an echo process sends it back). Then the same round trip through iotad's bus (`open_env_bus`,
Frames both ways) and its ratio to the baseline. Prints the tier first.

    .venv/bin/python bench/can.py [--count 2000] [--tier uml]

The host side picks the tier and runs the measuring part inside it (`--inside`); inside, the echo
peer is a second process (`--echo`). Figures only, no pass/fail on timings.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# This file is named can.py: drop its folder from the path, or `import can` would import it.
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))

ECHO_ID, REQUEST_ID, READY_ID, STOP_ID = 0x101, 0x100, 0x7F0, 0x7F1


def raw_bus():
    import can

    interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
    extra = {"port": 43113, "hop_limit": 1, "fd": False} if interface == "udp_multicast" else {}
    return can.Bus(interface=interface, channel=channel, **extra)


def echo() -> None:
    """The peer: answers every request frame with the same data under ECHO_ID (raw python-can)."""
    import can

    bus = raw_bus()
    bus.send(can.Message(arbitration_id=READY_ID, data=b"", is_extended_id=False))
    try:
        while True:
            message = bus.recv(timeout=30)
            if message is None or message.arbitration_id == STOP_ID:
                return
            if message.arbitration_id == REQUEST_ID:
                bus.send(can.Message(arbitration_id=ECHO_ID, data=message.data, is_extended_id=False))
            elif message.arbitration_id == READY_ID + 2:  # ping during start-up
                bus.send(can.Message(arbitration_id=READY_ID, data=b"", is_extended_id=False))
    finally:
        bus.shutdown()


def percentiles(samples: list[float]) -> dict:
    ordered = sorted(samples)
    pick = lambda q: ordered[min(len(ordered) - 1, int(q * len(ordered)))]  # noqa: E731
    return {"n": len(ordered), "p50_us": pick(0.50) * 1e6, "p99_us": pick(0.99) * 1e6,
            "mean_us": statistics.fmean(ordered) * 1e6, "max_us": ordered[-1] * 1e6}


def raw_round_trips(count: int) -> dict:
    import can

    bus = raw_bus()
    samples = []
    try:
        for k in range(count):
            data = k.to_bytes(4, "little") + b"\x00" * 4
            start = time.perf_counter()
            bus.send(can.Message(arbitration_id=REQUEST_ID, data=data, is_extended_id=False))
            while True:
                reply = bus.recv(timeout=2.0)
                if reply is None:
                    raise SystemExit(f"raw round trip {k}: no echo within 2 s")
                if reply.arbitration_id == ECHO_ID and bytes(reply.data) == data:
                    break
            samples.append(time.perf_counter() - start)
    finally:
        bus.shutdown()
    return percentiles(samples)


def iotad_round_trips(count: int) -> dict:
    from iotad.can.bus import open_env_bus
    from iotad.can.frame import Frame

    samples = []
    with open_env_bus() as bus:
        for k in range(count):
            frame = Frame(REQUEST_ID, k.to_bytes(4, "little") + b"\x00" * 4)
            start = time.perf_counter()
            bus.send_frame(frame)
            while True:
                got = bus.recv_frame(timeout=2.0)
                if got is None:
                    raise SystemExit(f"iotad round trip {k}: no echo within 2 s")
                if got[1].id == ECHO_ID and got[1].data == frame.data:
                    break
            samples.append(time.perf_counter() - start)
    return percentiles(samples)


def wait_for_echo(timeout: float = 20.0) -> None:
    import can

    bus = raw_bus()
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            bus.send(can.Message(arbitration_id=READY_ID + 2, data=b"", is_extended_id=False))
            reply = bus.recv(timeout=0.2)
            if reply is not None and reply.arbitration_id == READY_ID:
                return
        raise SystemExit("the echo process did not come up")
    finally:
        bus.shutdown()


def inside(count: int) -> None:
    """The measuring side, inside the tier: start the echo peer, measure, stop it."""
    import can

    peer = subprocess.Popen([sys.executable, __file__, "--echo"])
    try:
        wait_for_echo()
        raw_round_trips(min(200, count))  # warm-up
        raw = raw_round_trips(count)
        wrapped = iotad_round_trips(count)
        stop = raw_bus()
        stop.send(can.Message(arbitration_id=STOP_ID, data=b"", is_extended_id=False))
        stop.shutdown()
        peer.wait(timeout=10)
    finally:
        if peer.poll() is None:
            peer.kill()
            peer.wait()
    print("RESULT " + json.dumps({"raw": raw, "iotad": wrapped, "tier": os.environ.get("IOTAD_CAN_TIER")}))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=2000, help="round trips per measurement (2000)")
    parser.add_argument("--tier", help="vcan | uml | udp_multicast (default: the best here)")
    parser.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        echo()
        return 0
    if args.inside:
        inside(args.count)
        return 0
    from iotad.can.tiers import TierBus

    bus = TierBus(args.tier)
    print(f"CAN tier: {bus.describe()}  (interface {bus.interface}, channel {bus.channel})", flush=True)
    result = bus.run([sys.executable, __file__, "--inside", "--count", str(args.count)], timeout=300, cwd=str(ROOT))
    result.check()
    report = json.loads(next(l for l in result.output.splitlines() if l.startswith("RESULT "))[7:])
    raw, wrapped = report["raw"], report["iotad"]
    print(f"{'round trip, two processes':34} {'n':>6} {'p50 us':>9} {'p99 us':>9} {'mean us':>9} {'max us':>9}")
    for name, figures in (("raw python-can (baseline)", raw), ("iotad.can.bus (send/recv_frame)", wrapped)):
        print(f"{name:34} {figures['n']:6d} {figures['p50_us']:9.1f} {figures['p99_us']:9.1f} "
              f"{figures['mean_us']:9.1f} {figures['max_us']:9.1f}")
    print(f"iotad.can.bus / raw: p50 x{wrapped['p50_us'] / raw['p50_us']:.2f}, "
          f"p99 x{wrapped['p99_us'] / raw['p99_us']:.2f}   (run took {result.seconds:.1f} s, tier {bus.name})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
