"""Per-frame equivalence of recording formats 1 and 2: a system run in virtual time with each
bus modelled as format 1's `CanBus` and as format 2's `BurstCanBus` carries the same frames.

    .venv/bin/python bench/burst_equivalence.py [--system examples/conveyor.toml] [--until 2]

Both runs are recorded (as `iotad run --virtual -o F --format 1|2` records them) and read back;
for every bus, the frames it carried (station, id, flags, DLC, data, wire start and end: the
`frames` log of format 1, the bursts of format 2) must be equal in number, order and value, and
so must every node's `can_tx` outputs and `can_rx` inputs (time and frame). Prints the counts
and exits 0 when they agree, 1 with the first difference otherwise.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.append(str(ROOT))

from iotad.kernel.clock import VirtualClock  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.system.in_process import compose  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402
from iotad.recording.bursts import wire_frames  # noqa: E402
from iotad.recording.engine_sink import EngineRecorder  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402
from iotad.recording.mcap_sink import McapSink  # noqa: E402


def record(system_file: Path, until: float, recording_format: int, output: Path):
    system = load_system(system_file)
    root = compose(system, recording_format)
    sink = McapSink(output)
    try:
        recorder = EngineRecorder(sink, root, system.name, time_unit=system.time_unit)
        engine = Engine(root, VirtualClock(), sinks=[recorder])
        engine.run(until)
    finally:
        sink.finish()
        for leaf in engine.flat.leaves if "engine" in locals() else ():
            close = getattr(leaf.iota, "close", None)
            if callable(close):
                close()
    return system, read_recording(output)


def _on_grid(frame: dict) -> dict:
    """A frame with its wire times in whole nanoseconds (the engine's time grid): format 1's start
    is its end less its duration, format 2's the end of the frame before it."""
    return dict(frame, start=round(frame["start"] * 1e9), end=round(frame["end"] * 1e9))


def node_frames(recording, action: str) -> dict:
    out: dict = {}
    for event in recording.trace():
        if event["action"] == action and event["kind"] in ("input", "output"):
            value = event["value"]
            out.setdefault(event["node"], []).append((event["t"], value["id"], value["rtr"], value["dlc"],
                                                      list(value["data"])))
    return out


def compare(system_file: Path, until: float) -> tuple[bool, list[str]]:
    lines = []
    with tempfile.TemporaryDirectory() as folder:
        system, one = record(system_file, until, 1, Path(folder) / "format1.mcap")
        _, two = record(system_file, until, 2, Path(folder) / "format2.mcap")
        lines.append(f"{system_file.name}, {until:g} s: format {one.format_version} {len(one.messages)} messages "
                     f"in the file, format {two.format_version} {len(two.messages) - sum(m.derived for m in two.messages)}")
        for bus in system.buses:
            a, b = wire_frames(one, bus), wire_frames(two, bus)
            lines.append(f"  bus {bus}: {len(a)} frames in format 1, {len(b)} in format 2")
            if len(a) != len(b):
                return False, lines + [f"  bus {bus}: frame counts differ"]
            for k, (x, y) in enumerate(zip(a, b)):
                if _on_grid(x) != _on_grid(y):
                    return False, lines + [f"  bus {bus}: frame #{k} differs: format 1 {x}, format 2 {y}"]
        for action in ("can_tx", "can_rx"):
            a, b = node_frames(one, action), node_frames(two, action)
            if a != b:
                for node in sorted(set(a) | set(b)):
                    if a.get(node) != b.get(node):
                        first = next((k for k, (x, y) in enumerate(zip(a.get(node, []), b.get(node, []))) if x != y),
                                     min(len(a.get(node, [])), len(b.get(node, []))))
                        return False, lines + [f"  {node} {action} differs at #{first}"]
            lines.append(f"  {action}: {sum(map(len, a.values()))} frames, the same in both")
    return True, lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--system", type=Path, default=ROOT / "examples" / "conveyor.toml")
    parser.add_argument("--until", type=float, default=2.0, help="virtual seconds of each run")
    args = parser.parse_args()
    same, lines = compare(args.system, args.until)
    print("\n".join(lines))
    print("the same frames, ids, data and wire times in both formats" if same else "DIFFERENT")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
