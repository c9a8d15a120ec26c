"""Soak: a steady ping-pong load run by `iotad run` for a while; is anything lost, does anything grow?

    .venv/bin/python bench/soak.py                 10 minutes (the default), 250 round trips/s
    .venv/bin/python bench/soak.py --minutes 1     a short try
    .venv/bin/python bench/soak.py --minutes 30    the figure issue 15 asks for

A `Ping` node sends 0, 1, 2... at --rate Hz to a `Pong` node that echoes each back: four trace
events per round trip (ping's output, pong's input and output, ping's input), so 250 Hz is about
1,000 events a second. `iotad run` supervises both and records everything (trace-sourced, as
always). Printed:
- events recorded against events published: each node numbers its trace events and each
  output its messages from 0 (`seq`); published = the highest number + 1, recorded = what the
  file holds (zero lost means equal), with the recorder's own gap count;
- resident size (VmRSS) of every process (launcher, nodes, recorder) at the start (after the
  warm-up), after 1 minute and at the end, the growth per minute after minute 1 (least squares
  over all samples) and, for the recorder, that growth extrapolated to minute 30 (limit: 10 MB
  more than after minute 1);
- round-trip latency (ping's output -> ping's input of the echo, both in ping's clock) p50/p99
  in the first and in the last minute (a third of the run each, for runs under 3 minutes), and
  their ratio: the baseline is the run's own first minute.
Everything runs on loopback in a temp dir, removed at the end. Wall-clock sensitive by nature (a
loaded machine sends fewer pings), hence a bench, not a test.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad import Input, Int, Iota, Output, Param  # noqa: E402


class Ping(Iota):
    """Sends a counter every `period` seconds and counts the echoes."""
    period = Param(0.0025)
    pong = Input(Int(0, None))
    ping = Output(Int(0, None), switching=0.001)

    def init(self):
        self.sent = 0
        self.echoes = 0

    @pong.input
    def got(self, x):
        self.echoes += 1

    @ping.action(value=lambda self: self.sent, after="period")
    def fired(self):
        self.sent += 1


class Pong(Iota):
    """Echoes every ping at once."""
    ping = Input(Int(0, None), switching=0.001)
    pong = Output(Int(0, None))

    def init(self):
        self.pending = []

    @ping.input
    def got(self, x):
        self.pending.append(x)

    @pong.action(value=lambda self: self.pending[0], when=lambda self: len(self.pending) > 0)
    def sent(self):
        del self.pending[0]


SYSTEM = """
[system]
name = "soak"
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]
[[node]]
name = "ping"
python = "{me}:Ping"
params = {{ period = {period} }}
[[node]]
name = "pong"
python = "{me}:Pong"
[[bind]]
from = "ping.ping"
to = "pong.ping"
[[bind]]
from = "pong.pong"
to = "ping.pong"
"""


def rss_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def children(pid: int) -> dict[str, int]:
    """The launcher's children by role: node name (from its config path) or 'recorder'."""
    found = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as stat:
                if int(stat.read().rsplit(")", 1)[1].split()[1]) != pid:
                    continue
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                argv = cmdline.read().decode(errors="replace").split("\0")
        except (OSError, IndexError, ValueError):
            continue
        if "record" in argv:
            found["recorder"] = int(entry)
        else:
            config = next((a for a in argv if a.endswith(".json")), None)
            if config:
                found[Path(config).stem] = int(entry)
    return found


def positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def slope_per_min(points: list[tuple[float, float]]) -> float:
    """Least-squares growth (value units per minute) of (seconds, value) points."""
    if len(points) < 2:
        return 0.0
    n = len(points)
    mt = sum(t for t, _ in points) / n
    mv = sum(v for _, v in points) / n
    var = sum((t - mt) ** 2 for t, _ in points)
    return 60 * sum((t - mt) * (v - mv) for t, v in points) / var if var else 0.0


def analyse(recording: Path) -> dict:
    """Stream the recording once (it may not fit in memory): counts and round trips."""
    from iotad.recording.mcap_reader import iter_messages
    recorded: dict[str, int] = {}
    top: dict[str, int] = {}
    sent_at: dict[int, float] = {}
    trips: list[tuple[float, float]] = []  # (send t, round trip s)
    gaps = 0
    for message in iter_messages(recording):
        topic = message.topic
        if topic == "@recorder/gaps":
            gaps += 1
            continue
        if topic.endswith("/@heartbeat") or topic.endswith("/@launcher"):
            continue
        recorded[topic] = recorded.get(topic, 0) + 1
        top[topic] = max(top.get(topic, -1), message.sequence)
        if topic == "iota/soak/ping/@trace":
            event = message.value
            if event.get("kind") == "output" and event.get("action") == "ping":
                sent_at[event["value"]] = event["t"]
            elif event.get("kind") == "input" and event.get("action") == "pong":
                t0 = sent_at.pop(event["value"], None)
                if t0 is not None:
                    trips.append((t0, event["t"] - t0))
    return {"recorded": recorded, "published": {k: v + 1 for k, v in top.items()}, "gaps": gaps, "trips": trips}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=positive, default=10.0, help="how long to run under load (default 10)")
    parser.add_argument("--rate", type=positive, default=250.0,
                        help="round trips per second (default 250: ~1,000 events/s)")
    parser.add_argument("--warmup", type=positive, default=5.0, help="seconds before the first RSS sample")
    parser.add_argument("--every", type=positive, default=5.0, help="seconds between RSS samples")
    args = parser.parse_args()
    if args.warmup >= args.minutes * 60:
        parser.error("--warmup must be shorter than the run (--minutes)")

    from iotad.node_host.transport import free_port
    from iotad.launcher.processes import interrupt_then_kill

    with tempfile.TemporaryDirectory(prefix="iotad-soak-") as tmp:
        tmp = Path(tmp)
        system_file = tmp / "soak.toml"
        system_file.write_text(SYSTEM.format(port=free_port(), me=Path(__file__).resolve(), period=1 / args.rate))
        recording = tmp / "soak.mcap"
        total = args.minutes * 60
        out = open(tmp / "launcher.out", "wb")
        launcher = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(system_file), "--plain",
                                     "--until", str(total), "--log-dir", str(tmp / "logs"), "-o", str(recording)],
                                    cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        samples: list[tuple[float, dict[str, int | None]]] = []
        try:
            started = time.monotonic()
            roles: dict[str, int] = {}
            while launcher.poll() is None:
                now = time.monotonic() - started
                if now >= args.warmup and (not samples or now - samples[-1][0] >= args.every) and now < total - 1:
                    roles = {**roles, **children(launcher.pid)}
                    sample = {"launcher": rss_kb(launcher.pid)}
                    sample.update({role: rss_kb(pid) for role, pid in sorted(roles.items())})
                    samples.append((now, sample))
                time.sleep(0.1)
            code = launcher.wait(60)
        finally:
            interrupt_then_kill(launcher, 15)
            out.close()
        text = (tmp / "launcher.out").read_text()
        if code != 0 or len(samples) < 2:
            print(text[-3000:])
            print(f"launcher exit {code}; {len(samples)} samples")
            return 1
        figures = analyse(recording)
        size = sum(f.stat().st_size for f in tmp.glob("soak*.mcap"))

        (t0, first), (t1, last) = samples[0], samples[-1]
        at_1min = next(((t, s) for t, s in samples if t >= 60), None)
        print(f"soak: ping-pong at {args.rate:g} round trips/s for {t1 - t0 + args.warmup:.0f} s "
              f"(--minutes {args.minutes:g}); python {sys.version.split()[0]}, {os.cpu_count()} cpus")
        print("events recorded / published (published: highest seq + 1 of each stream):")
        lost_total = 0
        for topic in sorted(figures["published"]):
            published, recorded = figures["published"][topic], figures["recorded"][topic]
            lost_total += published - recorded
            print(f"  {topic:<28} {recorded:>9} / {published:<9} lost {published - recorded}")
        print(f"  total lost {lost_total}; recorder gaps {figures['gaps']}; recording {size / 2**20:.1f} MB")
        print(f"resident size (MB): start (t={t0:.0f} s)"
              + (", after 1 min" if at_1min else "") + f", end (t={t1:.0f} s); growth per minute after minute 1")
        for role in last:
            a, b = first.get(role), last.get(role)
            if a is None or b is None:
                print(f"  {role:<10} (not sampled throughout)")
                continue
            since = [(t, s[role] / 1024) for t, s in samples if t >= 60 and s.get(role)] or \
                    [(t, s[role] / 1024) for t, s in samples if s.get(role)]
            slope = slope_per_min(since)
            one = f"{at_1min[1][role] / 1024:>8.1f}" if at_1min and at_1min[1].get(role) else " " * 8
            line = f"  {role:<10} {a / 1024:>8.1f} {one} {b / 1024:>8.1f}   {slope:+.3f} MB/min"
            if role == "recorder":
                line += f"; extrapolated to minute 30: {slope * 29:+.1f} MB over minute 1 (limit +10 MB)"
            print(line)
        trips = figures["trips"]
        if trips:
            begin, end = trips[0][0], trips[-1][0]
            window = min(60.0, (end - begin) / 3)
            early = [rtt for t, rtt in trips if t < begin + window]
            late = [rtt for t, rtt in trips if t >= end - window]
            p99a, p99b = percentile(early, 0.99), percentile(late, 0.99)
            print(f"round trip ping -> pong -> ping ({len(trips)} trips; windows of {window:.0f} s):")
            print(f"  first: p50 {percentile(early, 0.5) * 1e3:.2f} ms  p99 {p99a * 1e3:.2f} ms ({len(early)} trips)")
            print(f"  last:  p50 {percentile(late, 0.5) * 1e3:.2f} ms  p99 {p99b * 1e3:.2f} ms ({len(late)} trips)"
                  f"   p99 last/first = {p99b / p99a:.2f}")
        for line in text.splitlines():
            if "violations:" in line or "restarted" in line or "gave up" in line:
                print("  " + line.strip())
    return 0


if __name__ == "__main__":
    sys.exit(main())
