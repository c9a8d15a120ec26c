"""The delivery check on CAN buses (`iotad run --virtual` with a [[can]] bus): each station's
can_tx frames against the bus's own log of the frames it carried and against the other
stations' can_rx; frames removed, changed or made up are caught and named; a frame on the bus
when --until stops the run is not judged; can_motor's frames reach the simulated ODrives."""
from dataclasses import replace
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording
from system_iotas import pingpong_system
from wire_tamper import index_of, rewrite, with_value

ROOT = Path(__file__).resolve().parents[2]
SYSTEM = pingpong_system(0.01)


def record(directory: Path, until: str, *options: str) -> Path:
    (directory / "pingpong.toml").write_text(SYSTEM)
    out = directory / "pingpong.mcap"
    assert main(["run", str(directory / "pingpong.toml"), "--virtual", "--until", until, "-o", str(out),
                 *options]) == 0
    return out


@pytest.fixture(scope="module")
def pingpong(tmp_path_factory):
    return record(tmp_path_factory.mktemp("pingpong"), "0.1")


@pytest.fixture(scope="module")
def pingpong_format1(tmp_path_factory):
    """Recording format 1: the bus logs each frame on its own `frames` message, as a real-time
    bus's logger still does in format 2 (the bus-log mutations below are of such a log)."""
    return record(tmp_path_factory.mktemp("pingpong1"), "0.1", "--format", "1")


def is_burst_with_pings(value):
    return value.get("action") == "burst" and any(f["station"] == 0 for f in value["value"])


def in_a_burst(messages, change):
    """`change(frames)` applied to the 4th burst that holds a ping, in the bus's trace and on
    its `burst` key alike (the wire holds what the trace says)."""
    k = index_of(messages, "iota/pingpong/can0/@trace", is_burst_with_pings, nth=3)
    event = messages[k].value
    frames = change(event["value"])
    messages[k] = with_value(messages[k], dict(event, value=frames))
    wire = next(n for n, m in enumerate(messages)
                if m.topic == "iota/pingpong/can0/burst" and m.log_time == messages[k].log_time)
    messages[wire] = with_value(messages[wire], frames)
    return messages


def dropped_from_a_burst(messages):
    return in_a_burst(messages, lambda frames: [f for f in frames if f["station"] != 0])


def made_up_in_a_burst(messages):
    def add(frames):
        frame = next(f for f in frames if f["station"] == 0)
        return frames + [dict(frame, id=0x7FF, start=frame["end"], end=frame["end"] + frame["duration"])]
    return in_a_burst(messages, add)


def links(path):
    report = check_delivery(read_recording(path))
    return report, {link.label: link for link in report.links}


def is_echo_rx(value):
    return value.get("kind") == "input" and value.get("action") == "can_rx"


def test_every_frame_is_on_the_bus_and_reaches_the_other_station(pingpong, capsys):
    assert main(["check", str(pingpong)]) == 0
    assert "every message was delivered as sent" in capsys.readouterr().out
    report, by_label = links(pingpong)
    for label in ("can can0: pinger -> (bus)", "can can0: pinger -> echo", "can can0: echo -> (bus)",
                  "can can0: echo -> pinger"):
        assert by_label[label].sent >= 9 and by_label[label].problems == 0
        # a 1-byte standard frame at 1 Mbit/s occupies the bus for about 60 us
        assert 50e-6 < by_label[label].latency()[0] < 100e-6


def dropped_receipt(messages):
    del messages[index_of(messages, "iota/pingpong/echo/@trace", is_echo_rx, nth=3)]
    return messages


def changed_receipt(messages):
    k = index_of(messages, "iota/pingpong/echo/@trace", is_echo_rx, nth=3)
    event = messages[k].value
    messages[k] = with_value(messages[k], dict(event, value=dict(event["value"], data=[99] + [0] * 7)))
    return messages


def dropped_from_bus_log(messages):
    del messages[index_of(messages, "iota/pingpong/can0/frames", lambda v: v["station"] == 0, nth=3)]
    return messages


def made_up_on_bus_log(messages):
    k = index_of(messages, "iota/pingpong/can0/frames", lambda v: v["station"] == 0, nth=3)
    frame = dict(messages[k].value, id=0x7FF)
    messages.insert(k + 1, replace(messages[k], sequence=9999, publish_time=messages[k].publish_time + 1,
                                   log_time=messages[k].log_time + 1, data=packb(frame)))
    return messages


# In format 2 the bus's log is its bursts, and its deliveries too: a frame dropped from one is
# lost on the bus, and the station that received it took a frame the bus never delivered; a frame
# made up is unexplained on the bus and delivered to a station that never took it. (The bus also
# no longer conforms: re-run on its inputs, its bursts differ.)
DROPPED_FROM_A_BURST = {("lost", "can can0: pinger -> (bus)"), ("unexplained", "can0.rx[1] -> echo.can_rx")}
MADE_UP_IN_A_BURST = {("unexplained", "can can0: pinger -> (bus)"), ("lost", "can0.rx[1] -> echo.can_rx")}


@pytest.mark.parametrize("recorded, mutation, expected", [
    ("pingpong", dropped_receipt, {("lost", "can can0: pinger -> echo"), ("lost", "can0.rx[1] -> echo.can_rx")}),
    ("pingpong", changed_receipt, {("altered", "can can0: pinger -> echo"), ("altered", "can0.rx[1] -> echo.can_rx")}),
    ("pingpong_format1", dropped_receipt,
     {("lost", "can can0: pinger -> echo"), ("lost", "can0.rx[1] -> echo.can_rx")}),
    ("pingpong_format1", changed_receipt,
     {("altered", "can can0: pinger -> echo"), ("altered", "can0.rx[1] -> echo.can_rx")}),
    ("pingpong_format1", dropped_from_bus_log,
     {("lost", "can can0: pinger -> (bus)"), ("lost", "can0.frames -> (wire)")}),
    ("pingpong_format1", made_up_on_bus_log,
     {("unexplained", "can can0: pinger -> (bus)"), ("unexplained", "can0.frames -> (wire)")}),
    ("pingpong", dropped_from_a_burst, DROPPED_FROM_A_BURST),
    ("pingpong", made_up_in_a_burst, MADE_UP_IN_A_BURST),
], ids=["dropped_receipt", "changed_receipt", "dropped_receipt_format1", "changed_receipt_format1",
        "dropped_from_bus_log_format1", "made_up_on_bus_log_format1", "dropped_from_a_burst", "made_up_in_a_burst"])
def test_a_frame_lost_changed_or_made_up_is_caught_and_named(recorded, request, tmp_path, capsys, mutation, expected):
    path = rewrite(request.getfixturevalue(recorded), tmp_path / "m.mcap", mutation)
    report, _ = links(path)
    assert {(f.code, f.link) for f in report.findings if f.problem} == expected
    if "bus_log" in mutation.__name__:  # the bus's log alone changed: every node still conforms
        assert main(["check", str(path), "--no-delivery"]) == 0
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert all(f"[{code}] {link}:" in out for code, link in expected)


def test_a_frame_on_the_bus_when_until_stops_the_run_is_not_judged(tmp_path, capsys):
    # pings go out at 0.01, 0.02, ...; each takes ~60 us on the bus: 0.05003 ends mid-frame
    path = record(tmp_path, "0.05003")
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "[not judged] can can0: pinger -> echo: frame 0x010 [04]: in flight when the run ended" in out
    # on the bus's side the run's end says where it was: on the wire, with its wire times
    assert "[not judged] can can0: pinger -> (bus): frame 0x010 [04]: cut at the end: on the wire when the run " \
           "ended at t=0.05003" in out


def test_can_motor_frames_reach_the_bus_and_the_simulated_odrives(tmp_path, capsys):
    pytest.importorskip("pybullet")
    out = tmp_path / "arm.mcap"
    assert main(["run", str(ROOT / "examples" / "arm_can.toml"), "--virtual", "--until", "0.3", "-o", str(out)]) == 0
    report, by_label = links(out)
    assert report.ok, report.lines()
    stations = read_recording(out).info.get("nodes")
    bus = next(label.split(":")[0][4:] for label in by_label if label.startswith("can "))
    for label in (f"can {bus}: motor -> (bus)", f"can {bus}: motor -> odrives", f"can {bus}: odrives -> motor"):
        link = by_label[label]
        assert link.delivered > 50 and link.problems == 0, (label, stations)
        assert link.delivered + link.unjudged == link.sent  # the rest: still queued at t=0.3


def test_a_bus_log_that_cannot_tell_the_sender_is_matched_by_content(pingpong_format1, tmp_path):
    """A listen-only logger on a real bus sees frames, not who sent them: `station` left out."""
    def anonymous(messages):
        return [with_value(m, {k: v for k, v in m.value.items() if k != "station"})
                if m.topic == "iota/pingpong/can0/frames" else m for m in messages]
    report, by_label = links(rewrite(pingpong_format1, tmp_path / "m.mcap", anonymous))
    # the bus model's own trace still says `station`: only its log on the wire differs from it
    assert {f.link for f in report.findings if f.problem} == {"can0.frames -> (wire)"}
    for station in ("pinger", "echo"):
        link = by_label[f"can can0: {station} -> (bus)"]
        assert link.delivered >= 9 and link.delivered + link.unjudged == link.sent  # the rest: on the bus at the end
