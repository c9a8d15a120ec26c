"""`iotad merge` of recording format 2 files from two hosts' recorders: a bus logger's bursts and a
station's `can_tx_burst` outputs that both recorders wrote are kept once (the owning host's copy,
moved onto the hub's clock), the bursts only the host's own file holds (the host cut off from the
hub) fill the hub's gap, and read back the merged file has every frame once, in the bus's order,
each at its own time: as many frames as the bus carried, none twice."""
import subprocess
import sys

from iotad.recording.bursts import wire_frames
from iotad.recording.mcap_format import FORMAT, packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from iotad.recording.merge import merge, merged_gaps, write_merged

SYSTEM = """
[system]
name = "split"
hub_host = "brain"
[system.endpoints]
listen = ["tcp/10.0.0.1:7447"]
[hosts.brain]
listen = ["tcp/10.0.0.1:0"]
[hosts.arm]
listen = ["tcp/10.0.0.2:0"]

[[node]]
name = "pinger"
host = "arm"
python = "requesters.py:Requester"
[[node]]
name = "echo"
host = "brain"
python = "requesters.py:Requester"

[[can]]
name = "can0"
interface = "socketcan"
channel = "vcan0"
stations = ["pinger", "echo"]
"""
ORIGIN = 1_700_000_000.0
AHEAD = 0.05  # the arm's clock is 50 ms ahead of the hub's
MS = 1_000_000
LOG_TRACE, LOG_KEY = "iota/split/can0/@trace", "iota/split/can0/burst"
PINGER_TRACE, PINGER_KEY = "iota/split/pinger/@trace", "iota/split/pinger/can_tx_burst"
CUT = (2.5, 4.5)  # the arm cut off from the hub: the hub's file lacks what the arm did then


def ns(t: float) -> int:
    return round((ORIGIN + t) * 1e9)


def frame(ident: int, data: int) -> dict:
    return {"id": ident, "extended": False, "rtr": False, "dlc": 1, "data": [data] + [0] * 7}


def logged(order: int, end: float, f: dict) -> dict:
    """A frame as the real-time logger records it in a burst: no station, its arrival as its end."""
    return {"station": None, "order": order, "queued": end - 6e-5, "start": end - 6e-5, "end": end,
            "duration": 6e-5, **f, "direction": "NOT_ODRIVE", "message": "UNKNOWN"}


def second(k: int) -> tuple[list, list]:
    """At second k: the pinger's burst of two frames (at t = k) and the logger's burst of them and
    the echo's answers (heard within its 5 ms batch): (the pinger's messages, the logger's), each
    as (topic, run time, sequence, value) with the trace event and the channel's copy."""
    t = float(k)
    sent = [frame(0x10, k), frame(0x12, k)]
    heard = [logged(4 * k + n, t + 0.0002 * (n + 1), f)
             for n, f in enumerate(sent + [frame(0x11, k), frame(0x13, k)])]
    burst_t = t + 0.005
    pinger = [(PINGER_TRACE, t, 2 * k, {"t": t, "iota": "pinger", "action": "can_tx_burst", "index": None,
                                         "kind": "output", "value": sent}),
              (PINGER_KEY, t, k, sent)]
    log = [(LOG_TRACE, burst_t, k, {"t": burst_t, "iota": "can0", "action": "burst", "index": None,
                                    "kind": "output", "value": heard}),
           (LOG_KEY, burst_t, k, heard)]
    return pinger, log


def write(path, host, messages, *, hub=False, offset=None):
    sink = McapSink(path)
    run = {"host": host, "hub": hub, "origin": ORIGIN}
    if offset is not None:
        run["clock"] = {"offset": offset, "bound": 0.0002, "samples": 16, "measured_ns": ns(-1) - round(offset * 1e9)}
    sink.add_metadata("iotad.recording", {"format": FORMAT, "system": "split", "clock": "real", "source": "traces",
                                          "writer": "iotad record", "time_unit": 1.0, "run": run})
    sink.attach("system.toml", "application/toml", SYSTEM.encode())
    for topic, log_ns, publish_ns, sequence, value in sorted(messages, key=lambda m: m[1]):
        sink.write(sink.channel(topic, "t", {}), log_ns, publish_ns, sequence, packb(value))
    sink.finish()
    return path


def recorded(tmp_path):
    """The hub's file (the arm's messages 2 ms after they were sent, on the hub's clock; none during
    the cut) and the arm's (1 ms after, on its own clock, 50 ms ahead)."""
    on_hub, on_arm = [], []
    for k in range(1, 7):
        for topic, t, sequence, value in [m for part in second(k) for m in part]:
            sent = ns(t) + round(AHEAD * 1e9)  # the arm's nodes stamp their own clock
            on_arm.append((topic, sent + MS, sent, sequence, value))
            if not CUT[0] < t < CUT[1]:
                on_hub.append((topic, ns(t) + 2 * MS, sent, sequence, value))
    hub = write(tmp_path / "split.mcap", "brain", on_hub, hub=True)
    arm = write(tmp_path / "split.arm.mcap", "arm", on_arm, offset=-AHEAD)
    return hub, arm


def test_each_burst_is_kept_once_and_each_frame_reads_back_once(tmp_path):
    hub, arm = recorded(tmp_path)
    out = tmp_path / "merged.mcap"
    write_merged(merge([hub, arm]), out)
    merged = read_recording(out)
    assert merged.format_version == 2
    raw = [m for m in merged.messages if not m.derived]
    bursts = [m for m in raw if m.topic == LOG_TRACE]
    assert [m.value["t"] for m in bursts] == [k + 0.005 for k in range(1, 7)]  # once each, the cut's too
    # the arm's own copy, moved onto the hub's clock: 1 ms after the hub's time of sending
    assert [m.log_time for m in bursts] == [ns(k + 0.005) + MS for k in range(1, 7)]
    assert len([m for m in raw if m.topic == LOG_KEY]) == 6 and len([m for m in raw if m.topic == PINGER_TRACE]) == 6
    # read back: every frame the bus carried once, in the bus's order, at its arrival
    frames = wire_frames(merged, "can0")
    assert [(f["id"], f["data"][0]) for f in frames] == [(i, k) for k in range(1, 7) for i in (0x10, 0x12, 0x11, 0x13)]
    assert [f["end"] for f in frames] == [k + 0.0002 * (n + 1) for k in range(1, 7) for n in range(4)]
    log = [e for e in merged.trace("can0") if e["action"] == "frames"]
    assert [e["t"] for e in log] == [f["end"] for f in frames]
    on_key = [m for m in merged.messages if m.topic == "iota/split/can0/frames"]
    assert len(on_key) == 24 and [m.log_time for m in on_key] == sorted(m.log_time for m in on_key)
    # the pinger's bursts, each frame a can_tx once
    sent = [(e["t"], e["value"]["id"]) for e in merged.trace("pinger") if e["action"] == "can_tx"]
    assert sent == [(float(k), i) for k in range(1, 7) for i in (0x10, 0x12)]
    # what the hub missed is marked, and filled from the arm's file
    assert [g["host"] for g in merged_gaps(merged) if "did not reach the hub" in g["reason"]] == ["arm"]


def test_iotad_merge_then_check_reads_the_merged_bursts(tmp_path):
    hub, arm = recorded(tmp_path)
    out = tmp_path / "merged.mcap"
    run = subprocess.run([sys.executable, "-m", "iotad", "merge", str(hub), str(arm), "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    dump = subprocess.run([sys.executable, "-m", "iotad", "candump", str(out), "--log"], capture_output=True,
                          text=True, timeout=120)
    assert dump.returncode == 0, dump.stderr
    lines = dump.stdout.splitlines()
    assert len(lines) == 24 and all(line.split()[0] == "can0" for line in lines)
