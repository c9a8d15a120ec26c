"""Runs `iotad run --virtual -o` of the shipped Buggy, conveyor and Figure 2 systems with two
trees of the code (a baseline checkout and this one) and says whether their recordings hold the
same events, message for message: a restructuring of the code must not change what a run does.

    python bench/same_events.py [--baseline /work/main] [--tree .] [--keep DIR]

Both runs use the same venv (this interpreter); only PYTHONPATH differs. Compared: every MCAP
message (topic, log and publish time, the decoded payload), the attachments (specs, the system
file) and the metadata, less the wall-clock fields a run writes (when, which process, how fast).
Exit status 0 when all three agree, 1 with the first differences printed otherwise.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import msgpack
from mcap.reader import make_reader

ROOT = Path(__file__).resolve().parents[1]
# system file, virtual seconds: short, so that the three run twice in well under a minute
SYSTEMS = [("examples/buggy.toml", 4.0), ("examples/conveyor.toml", 3.0), ("examples/figure2.toml", 30.0)]
# metadata keys that hold the wall clock, the machine or the run's speed, not what the run did
WALL_CLOCK_KEYS = {"created", "created_ns", "wall_start", "wall_start_ns", "wall", "origin", "origin_ns",
                   "started", "stopped", "duration_s", "wall_s", "elapsed", "elapsed_s", "writer",
                   "pid", "hostname", "host", "written_by", "speed", "realtime_factor"}


def record(tree: Path, system: str, until: float, out: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(tree))
    done = subprocess.run([sys.executable, "-m", "iotad", "run", system, "--virtual", "--until", str(until),
                           "-o", str(out), "--plain"], cwd=tree, env=env, capture_output=True, text=True,
                          timeout=300)
    if done.returncode != 0:
        raise SystemExit(f"{tree}: iotad run {system} exited {done.returncode}:\n{done.stderr[-2000:]}")


def _plain(value):
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items() if k not in WALL_CLOCK_KEYS}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def _metadata_value(text: str):
    import json
    try:
        return _plain(json.loads(text))
    except ValueError:
        return text


def _untreed(data: bytes, tree: Path) -> bytes:
    """An attachment with the tree's own folder and the module names derived from it made neutral."""
    text = data.decode("utf-8", errors="surrogateescape").replace(str(tree), "<tree>")
    return re.sub(r"(_iotad_user_\w+?_)[0-9a-f]{16}", r"\1<hash>", text).encode("utf-8", errors="surrogateescape")


def contents(path: Path, tree: Path) -> dict:
    """What a recording says, less the wall clock and where its tree lies: messages in file order,
    attachments, metadata."""
    messages, attachments, metadata = [], {}, {}
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            try:
                data = msgpack.unpackb(message.data, raw=False, strict_map_key=False)
            except Exception:  # a JSON or raw payload: compare its bytes
                data = message.data
            messages.append((channel.topic, message.log_time, message.publish_time, message.sequence, data))
        for attachment in reader.iter_attachments():
            attachments[attachment.name] = _untreed(attachment.data, tree)
        for record in reader.iter_metadata():
            metadata[record.name] = {k: _metadata_value(v) for k, v in record.metadata.items() if k not in WALL_CLOCK_KEYS}
    return {"messages": messages, "attachments": attachments, "metadata": metadata}


def differences(a: dict, b: dict, limit: int = 5) -> list[str]:
    found = []
    if a["attachments"].keys() != b["attachments"].keys():
        found.append(f"attachments {sorted(a['attachments'])} != {sorted(b['attachments'])}")
    for name in sorted(a["attachments"].keys() & b["attachments"].keys()):
        if a["attachments"][name] != b["attachments"][name]:
            found.append(f"attachment {name} differs")
    if a["metadata"] != b["metadata"]:
        for name in sorted(a["metadata"].keys() | b["metadata"].keys()):
            if a["metadata"].get(name) != b["metadata"].get(name):
                found.append(f"metadata {name}: {a['metadata'].get(name)!r} != {b['metadata'].get(name)!r}")
    if len(a["messages"]) != len(b["messages"]):
        found.append(f"{len(a['messages'])} messages != {len(b['messages'])}")
    for i, (x, y) in enumerate(zip(a["messages"], b["messages"])):
        if x != y:
            found.append(f"message {i}: {x!r:.300} != {y!r:.300}")
            if len(found) >= limit:
                break
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", default="/work/main", help="the tree whose runs are the reference")
    parser.add_argument("--tree", default=str(ROOT), help="the tree under test (default: this one)")
    parser.add_argument("--keep", metavar="DIR", help="keep the recordings in DIR")
    args = parser.parse_args(argv)
    folder = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="same_events_"))
    folder.mkdir(parents=True, exist_ok=True)
    failed = False
    for system, until in SYSTEMS:
        stem = Path(system).stem
        runs = {}
        for label, tree in (("baseline", Path(args.baseline)), ("tree", Path(args.tree))):
            out = folder / f"{stem}_{label}.mcap"
            out.unlink(missing_ok=True)
            record(tree.resolve(), system, until, out)
            runs[label] = contents(out, tree.resolve())
        found = differences(runs["baseline"], runs["tree"])
        count = len(runs["tree"]["messages"])
        print(f"{system} --until {until}: {count} messages, " + ("same events" if not found else "DIFFERENT"))
        for line in found:
            print("   ", line)
        failed |= bool(found)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
