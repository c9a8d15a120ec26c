"""In real time each [[can]] bus has a bus logger, a listen-only node named after the bus: a
ping-pong over a CAN tier (`system_can_tier`) records the frames it hears in bursts (recording
format 2: `iota/pingpong/can0/burst`), read back as `iota/pingpong/can0/frames` with every frame
both stations sent (ids, data, each station's order), `iotad check` matches each station's can_tx
against it (`can can0: STATION -> (bus)`, clean), `iotad candump --log` prints it, and a frame a
station sent that the logger never heard is reported lost. The file says `interface = "env"`:
the tier's bus (IOTAD_CAN_INTERFACE, IOTAD_CAN_CHANNEL), whichever tier it is."""
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from pingpong import run_pingpong
from iotad.can.frame import Frame
from iotad.cli import main
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "recording"))
from wire_tamper import rewrite  # noqa: E402

LOG = "iota/pingpong/can0/frames"  # read back from the bursts
BURSTS, TRACE = "iota/pingpong/can0/burst", "iota/pingpong/can0/@trace"


def edit_log(messages, edit):
    """`messages` with `edit(frames) -> frames` applied to each burst the logger recorded: on its
    `burst` channel and in its trace, as a logger that heard otherwise would have written both."""
    out = []
    for m in messages:
        value = m.value
        if m.topic == BURSTS:
            m = replace(m, data=packb(edit(list(value))))
        elif m.topic == TRACE and isinstance(value, dict) and value.get("action") == "burst":
            m = replace(m, data=packb(dict(value, value=edit(list(value["value"])))))
        out.append(m)
    return out


@pytest.fixture(scope="module")
def pingpong(system_can_tier, tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("bus_log")
    return run_pingpong(system_can_tier, tmp_path)


def new_problems(original, report):
    """The problems `report` has that the untouched recording's report has not (a loaded tier may
    give the run problems of its own, which no mutation of the log explains)."""
    before = {(f.code, f.link, f.t, f.message) for f in check_delivery(read_recording(original)).findings if f.problem}
    return [f for f in report.findings if f.problem and (f.code, f.link, f.t, f.message) not in before]


def sent_by(recording, node):
    return [Frame.from_value(e["value"]) for e in recording.trace()
            if e.get("node", e.get("iota")) == node and e["action"] == "can_tx" and e["kind"] == "output"]


def test_the_log_holds_every_frame_both_stations_sent_in_their_order(pingpong):
    recording = read_recording(pingpong)
    logged = [m.value for m in recording.messages if m.topic == LOG]
    assert all(record["station"] is None for record in logged)  # a real bus does not say who sent it
    frames = [Frame.from_value(record) for record in logged]
    for node, ident in (("pinger", 0x10), ("echo", 0x11)):
        sent, heard = sent_by(recording, node), [f for f in frames if f.id == ident]
        assert len(heard) >= 10, (node, len(heard), len(sent))
        # the logger hears from its start on: a run of the station's frames, in its order; only
        # frames sent before it started or in flight at the stop may be missing
        first = sent.index(heard[0])
        assert sent[first:first + len(heard)] == heard, node
    # the frames are on the log's topic once each, and nowhere else: not once per receiver on a
    # topic named after the CAN port's input key (`can/can0`), which said nothing of who got them
    assert not [m.topic for m in recording.messages if not m.topic.startswith(("iota/", "@recorder/"))]
    # each answer is on the bus after the ping it answers
    order = {(f.id, f.data): k for k, f in enumerate(frames)}
    assert all(order[(0x10, f.data)] < k for k, f in enumerate(frames) if f.id == 0x11 and (0x10, f.data) in order)


def test_check_matches_each_station_against_the_log_and_candump_prints_it(pingpong, capsys):
    report = check_delivery(read_recording(pingpong))
    links = {link.label: link for link in report.links}
    for station in ("pinger", "echo"):
        link = links[f"can can0: {station} -> (bus)"]
        assert link.problems == 0 and link.delivered >= 10 and link.delivered + link.unjudged == link.sent, \
            [f.message for f in report.findings if f.link == link.label]
    assert links["can0.frames -> (wire)"].problems == 0
    main(["check", str(pingpong)])  # conformance may see deadline misses on a slow tier: not asserted
    out = capsys.readouterr().out
    assert "can can0: pinger -> (bus)" in out and "can can0: echo -> (bus)" in out
    assert main(["candump", str(pingpong), "--log"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == links["can0.frames -> (wire)"].sent
    assert all(line.split()[0] == "can0" and line.split()[2] == "frames" for line in lines)
    assert {line.split()[3] for line in lines} == {"010", "011"}


def test_a_frame_the_logger_never_heard_is_reported_lost(pingpong, tmp_path):
    recording = read_recording(pingpong)
    pings = [m.value for m in recording.messages if m.topic == LOG and m.value["id"] == 0x10]
    victim = pings[len(pings) // 2]["data"][0]

    def is_victim(value):
        value = value.get("value") if isinstance(value, dict) and "kind" in value else value
        return isinstance(value, dict) and value.get("id") == 0x10 and (value.get("data") or [None])[0] == victim

    def unheard(messages):  # the log and the logger's own trace (its can_rx and bursts) lose that ping
        kept = [m for m in messages if not (m.topic == TRACE and is_victim(m.value))]
        return edit_log(kept, lambda frames: [f for f in frames if not is_victim(f)])

    report = check_delivery(read_recording(rewrite(pingpong, tmp_path / "unheard.mcap", unheard)))
    new = new_problems(pingpong, report)
    assert [(f.code, f.link) for f in new] == [("lost", "can can0: pinger -> (bus)")]
    finding = new[0]
    assert f"frame 0x010 [{victim:02X}]" in finding.message and "never went on the bus" in finding.message


def test_a_frame_no_station_sent_is_a_note_and_a_changed_one_altered(pingpong, tmp_path):
    """The log's sender is unknown: a frame on it that no station's can_tx sent may be a device
    that is not a node (or a station's final frames), so it is a note, not a problem; one whose
    data changed while a station's frame of that id is missing is altered."""
    def made_up(messages):  # one more frame, 0x7FF, after the sixth the logger heard
        def edit(frames):
            out = []
            for f in frames:
                out.append(f)
                if f["order"] == 5:
                    out.append(dict(f, id=0x7FF))
            return out
        return edit_log(messages, edit)

    original = []

    def changed(messages):  # the sixth ping the logger heard carries other data
        pings = sorted(f["order"] for m in messages if m.topic == BURSTS for f in m.value if f["id"] == 0x10)
        sixth = pings[5]

        def edit(frames):
            out = []
            for f in frames:
                if f["order"] == sixth:
                    if len(original) < 1:
                        original.append(f["data"][0])
                    f = dict(f, data=[0xEE] + [0] * 7)
                out.append(f)
            return out
        return edit_log(messages, edit)

    report = check_delivery(read_recording(rewrite(pingpong, tmp_path / "made_up.mcap", made_up)))
    assert not new_problems(pingpong, report)  # the log says what the logger heard; no station's send explains it
    assert any(f.code == "foreign" and "0x7FF" in f.message and "no station's can_tx sent" in f.message
               for f in report.notes)
    report = check_delivery(read_recording(rewrite(pingpong, tmp_path / "changed.mcap", changed)))
    assert {(f.code, f.link) for f in new_problems(pingpong, report)} == {("altered", "can can0: pinger -> (bus)")}
    # the frame named is the one changed, not another of its id missing from the log (the pinger's
    # frames sent after the logger stopped are missing too)
    altered = next(f for f in report.findings if f.code == "altered" and f.link == "can can0: pinger -> (bus)")
    assert f"pinger sent frame 0x010 [{original[0]:02X}], the bus carried 0x010 [EE]" in altered.message
