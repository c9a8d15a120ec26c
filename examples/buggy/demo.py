"""`make demo`: Buggy as six processes in real time, recorded, then drawn like the paper's Figure 4.

    python examples/buggy/demo.py [--seconds 30] [--system examples/buggy.toml]

The system file's CAN bus is `interface = "env"`: the bus IOTAD_CAN_INTERFACE and
IOTAD_CAN_CHANNEL name. Where they are not set, the demo takes SocketCAN vcan0 if this host has
it, and else runs itself inside a CAN tier (`python -m iotad.can.tiers`, docs/can.md), which
sets them: preferably udp_multicast on the loopback of a private network namespace (native
speed), else whatever tier there is. (A system file that names its own bus is run inside the
tier as a copy whose [[can]] names the tier's.)
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=30.0, help="how long to run (s, at most 60)")
    parser.add_argument("--system", default=str(ROOT / "examples" / "buggy.toml"))
    parser.add_argument("--out", default=str(ROOT / "recordings"), help="folder for the recording and picture")
    args = parser.parse_args()
    seconds = min(max(args.seconds, 5.0), 60.0)
    if "IOTAD_CAN_INTERFACE" not in os.environ:
        if not Path("/sys/class/net/vcan0").exists():
            return _in_tier(seconds, args)
        os.environ.update(IOTAD_CAN_INTERFACE="socketcan", IOTAD_CAN_CHANNEL="vcan0")  # for "env" buses
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recording, picture = out / "buggy-demo.mcap", out / "buggy-demo.png"
    system = Path(args.system).resolve()
    with _on_tier_bus(system) as path:
        print(f"Buggy as processes in real time for {seconds:g} s (CAN: {_bus_words()})", flush=True)
        status = _call([str(BIN / "iotad"), "run", str(path), "--until", str(seconds), "-o", str(recording), "--force"])
    if status == 130:
        print(f"stopped; the recording is whole: {recording}", file=sys.stderr)
        return status
    if status != 0 or not recording.exists():
        print(f"the run failed (exit {status})", file=sys.stderr)
        return status or 1
    subprocess.call([str(BIN / "iotad"), "plot", str(recording), "-o", str(picture)])
    rel = lambda p: os.path.relpath(p, Path.cwd())  # noqa: E731
    print(f"""
recording: {rel(recording)}
picture:   {rel(picture)}   (the path coloured by behaviour; hunger and fear over time)

try next:
  .venv/bin/iotad info {rel(recording)}                  # what the recording holds
  .venv/bin/iotad check {rel(recording)}                 # every node against its spec
  .venv/bin/iotad replay {rel(recording)} --node body    # re-run a node on its recorded inputs and firing times
  .venv/bin/iotad run examples/buggy.toml --virtual --until 120 -o recordings/buggy.mcap   # 2 minutes, one process, seconds
  .venv/bin/iotad plot recordings/buggy.mcap -o recordings/buggy.png
  .venv/bin/iotad run examples/buggy-hungry.toml --virtual --until 120 -o recordings/buggy-hungry.mcap   # bolder when hungry
  .venv/bin/iotad export {rel(recording)} -o buggy-foxglove.mcap --json   # open in Foxglove: plot /body/pose.x, .y
  make test""")
    return 0


def _bus_words() -> str:
    return f"{os.environ.get('IOTAD_CAN_INTERFACE', 'socketcan')} {os.environ.get('IOTAD_CAN_CHANNEL', 'vcan0')}"


def _in_tier(seconds: float, args: argparse.Namespace) -> int:
    """Run this script again inside a CAN tier (udp_multicast if there is one)."""
    tiers = subprocess.run([sys.executable, "-m", "iotad.can.tiers"], capture_output=True, text=True).stdout
    tier = ["--tier", "udp_multicast"] if re.search(r"^udp_multicast\s+available", tiers, re.M) else []
    command = [sys.executable, "-m", "iotad.can.tiers", "run", *tier, "--timeout", str(int(seconds) + 120), "--",
               sys.executable, __file__, "--seconds", str(seconds), "--system", args.system, "--out", args.out]
    return _call(command)


def _call(command: list[str]) -> int:
    """`subprocess.call` that lets Ctrl-C stop the child its own way: the child got the signal
    too (a terminal's Ctrl-C, or the CAN tier passing it on), and a launcher stops its nodes and
    finishes its recording. (`subprocess.call` would kill it a quarter of a second later.)"""
    child = subprocess.Popen(command)
    while True:
        try:
            return child.wait()
        except KeyboardInterrupt:
            continue


class _on_tier_bus:
    """The system file, or a copy of it beside it whose [[can]] names the tier's bus."""

    def __init__(self, system: Path):
        self.system, self.copy = system, None

    def __enter__(self) -> Path:
        interface, channel = os.environ.get("IOTAD_CAN_INTERFACE"), os.environ.get("IOTAD_CAN_CHANNEL")
        text = self.system.read_text()
        if not interface or (interface, channel) == ("socketcan", "vcan0") or \
                re.search(r'^interface = "env"', text, flags=re.M):
            return self.system  # its bus already is, or is taken from the environment
        text = re.sub(r'^interface = "[^"]*"', f'interface = "{interface}"', text, flags=re.M)
        text = re.sub(r'^channel = "[^"]*"', f'channel = "{channel}"', text, flags=re.M)
        # beside the original: its relative paths (spec, python) stay right
        handle, name = tempfile.mkstemp(prefix=".demo-", suffix=".toml", dir=self.system.parent)
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        self.copy = Path(name)
        return self.copy

    def __exit__(self, *exc) -> None:
        if self.copy is not None:
            self.copy.unlink(missing_ok=True)


if __name__ == "__main__":
    sys.exit(main())
