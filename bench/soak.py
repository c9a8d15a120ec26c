"""Soak: a fast ping-pong pair run by `iotad run` for a while; does anything grow? (prints figures)

    .venv/bin/python bench/soak.py [--seconds 60] [--rate 400] [--no-record]

A `Ping` node sends 0, 1, 2... at --rate Hz to a `Pong` node that echoes each back; `iotad run`
supervises both and (unless --no-record) records everything. After a warm-up, the resident
memory (VmRSS) of the launcher, each node and the recorder is sampled every few seconds; the
table shows the first and last samples and the growth per minute, and the pair's heartbeats
show each node's input backlog. Everything runs on loopback in a temp dir, removed at the end.
Wall-clock sensitive by nature (a loaded machine sends fewer pings), hence a bench, not a test.
"""
from __future__ import annotations

import argparse
import os
import signal
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="how long to sample (after the warm-up)")
    parser.add_argument("--rate", type=float, default=400.0, help="pings per second")
    parser.add_argument("--warmup", type=float, default=5.0, help="seconds before the first sample")
    parser.add_argument("--every", type=float, default=5.0, help="seconds between samples")
    parser.add_argument("--no-record", action="store_true", help="run without the recorder")
    args = parser.parse_args()

    from iotad.recording.mcap_io import read_recording
    from iotad.host.transport import free_port

    with tempfile.TemporaryDirectory(prefix="iotad-soak-") as tmp:
        tmp = Path(tmp)
        system_file = tmp / "soak.toml"
        system_file.write_text(SYSTEM.format(port=free_port(), me=Path(__file__).resolve(), period=1 / args.rate))
        recording = tmp / "soak.mcap"
        record = ["--no-record"] if args.no_record else ["-o", str(recording)]
        total = args.warmup + args.seconds
        out = open(tmp / "launcher.out", "wb")
        launcher = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(system_file), "--plain",
                                     "--until", str(total + 2), "--log-dir", str(tmp / "logs"), *record],
                                    cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        samples: list[tuple[float, dict[str, int | None]]] = []
        try:
            started = time.monotonic()
            roles = {}
            while time.monotonic() - started < total:
                now = time.monotonic() - started
                if now >= args.warmup and (not samples or now - samples[-1][0] >= args.every):
                    roles = {**roles, **children(launcher.pid)}
                    sample = {"launcher": rss_kb(launcher.pid)}
                    sample.update({role: rss_kb(pid) for role, pid in sorted(roles.items())})
                    samples.append((now, sample))
                if launcher.poll() is not None:
                    break
                time.sleep(0.1)
            code = launcher.wait(60)
        finally:
            if launcher.poll() is None:
                launcher.send_signal(signal.SIGINT)
                try:
                    launcher.wait(15)
                except subprocess.TimeoutExpired:
                    os.killpg(launcher.pid, signal.SIGKILL)
                    launcher.wait()
            out.close()
        text = (tmp / "launcher.out").read_text()
        if code != 0 or len(samples) < 2:
            print(text[-3000:])
            print(f"launcher exit {code}; {len(samples)} samples")
            return 1
        (t0, first), (t1, last) = samples[0], samples[-1]
        minutes = (t1 - t0) / 60
        print(f"soak: ping-pong at {args.rate:g} Hz for {t1 - t0:.0f} s after a {args.warmup:g} s warm-up "
              f"({'no recorder' if args.no_record else 'recorded'}); python {sys.version.split()[0]}, "
              f"{os.cpu_count()} cpus")
        print(f"  {'process':<10} {'RSS first':>10} {'RSS last':>10} {'growth':>9} {'per min':>9}")
        for role in last:
            a, b = first.get(role), last.get(role)
            if a is None or b is None:
                print(f"  {role:<10} (not sampled throughout)")
                continue
            print(f"  {role:<10} {a / 1024:>8.1f}MB {b / 1024:>8.1f}MB {(b - a) / 1024:>+7.1f}MB "
                  f"{(b - a) / 1024 / minutes:>+7.2f}MB")
        print("  RSS over time (MB): " + "; ".join(
            f"{t:.0f}s " + " ".join(f"{r}={(v or 0) / 1024:.1f}" for r, v in s.items()) for t, s in samples))
        for line in text.splitlines():
            if "ping.ping" in line or "pong.pong" in line or "violations:" in line or "restarted" in line:
                print("  " + line.strip())
        if not args.no_record:
            rec = read_recording(recording)
            for node in ("ping", "pong"):
                beats = [m.value for m in rec.messages if m.topic == f"iota/soak/{node}/@heartbeat"]
                if beats:
                    print(f"  {node} heartbeats: {len(beats)}, input backlog max {max(b['queue'] for b in beats)}, "
                          f"firings {beats[-1]['firings']}")
            print(f"  recording: {recording.stat().st_size / 2**20:.1f} MB, {len(rec.messages)} messages, "
                  f"complete={rec.complete}, gaps={len(rec.gaps())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
