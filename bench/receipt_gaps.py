"""The longest stretch without a message, per key, in each recording of a run: how long a recorder
heard nothing of a stream that flows steadily (a pulse's outputs, a node's heartbeats), on its
receipt times. A partition test's files show what a cut did to the streams that should not have
noticed it (prints figures; asserts nothing).

    .venv/bin/python bench/receipt_gaps.py RECORDING.mcap [...] [--min 20] [--keys out,@heartbeat] [--latency]

For each file and each key with at least --min messages whose last part is one of --keys: the
number of messages, the longest gap between two receipts (s) and when it began, in seconds of
the run (from the run's origin in the file's metadata). With --latency, the files (one run's,
each host's) are merged as `iotad merge` does, and for each binding: how many messages were
delivered, their latency from the sender's firing to the receiver's input (p50, p99, max) and how
many were lost (`iotad.recording.delivery`).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad.recording.delivery import check_delivery  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402
from iotad.recording.merge import merge  # noqa: E402


def gaps(path: Path, least: int, suffixes: set[str]) -> list[tuple[str, int, float, float]]:
    recording = read_recording(path)
    origin = recording.info.get("run", {}).get("origin") or 0.0
    times: dict[str, list[int]] = {}
    for message in recording.messages:
        if message.topic.rsplit("/", 1)[-1] in suffixes:
            times.setdefault(message.topic, []).append(message.log_time)
    rows = []
    for topic, stamps in sorted(times.items()):
        if len(stamps) < least:
            continue
        stamps.sort()
        longest, at = max((b - a, a) for a, b in zip(stamps, stamps[1:]))
        rows.append((topic, len(stamps), longest / 1e9, at / 1e9 - origin))
    return rows


def latencies(paths: list[Path]) -> list[str]:
    report = check_delivery(merge(paths).recording if len(paths) > 1 else read_recording(paths[0]))
    lines = []
    for link in report.links:
        if link.kind != "binding":
            continue
        times = sorted(latency for label, _, latency, _ in report.deliveries if label == link.label)
        if times:
            lines.append(f"{link.label}: {len(times)} delivered, latency p50 {times[len(times) // 2] * 1e3:.2f} ms, "
                         f"p99 {times[int(len(times) * 0.99)] * 1e3:.2f} ms, max {times[-1] * 1e3:.1f} ms; {link.lost} lost")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recordings", nargs="+", type=Path)
    parser.add_argument("--min", type=int, default=20, help="keys with fewer messages are left out")
    parser.add_argument("--keys", default="out,@heartbeat", help="last parts of the keys to measure")
    parser.add_argument("--latency", action="store_true", help="merge the files and print each binding's latency")
    args = parser.parse_args()
    for path in args.recordings:
        for topic, count, longest, at in gaps(path, args.min, set(args.keys.split(","))):
            print(f"{path.name}: {topic}: {count} messages, longest gap {longest:.3f} s from t={at:.1f} s")
    if args.latency:
        print("\n".join(latencies(args.recordings)))


if __name__ == "__main__":
    main()
