"""`iotad merge` joins the recordings of one run's hosts, on small recordings built by hand: host
files are moved onto the hub's clock by their recorded offset and ordered by it, a message both
files hold is kept once (the owning host's copy), every stretch where a host's events are missing
from a recording is a marked gap naming the host and the interval, a recorder's sequence gap that
another file filled is gone, and files that do not belong together are one clear error."""
import os
import subprocess
import sys

import pytest

from iotad.recording.mcap_format import FORMAT, GAP_TOPIC, packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from iotad.recording.merge import MergeError, merge, merged_gaps, write_merged

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
[hosts.base]
listen = ["tcp/10.0.0.3:0"]

[[node]]
name = "scheduler"
host = "brain"
python = "scheduler.py:Scheduler"
[[node]]
name = "vision"
host = "arm"
python = "requesters.py:Requester"
[[node]]
name = "wheels"
host = "base"
python = "requesters.py:Requester"
"""
ORIGIN = 1_700_000_000.0
AHEAD = 0.05  # the arm's clock is 50 ms ahead of the hub's: its offset to the hub is -50 ms
MS = 1_000_000
SCHEDULER, VISION = "iota/split/scheduler/@trace", "iota/split/vision/@trace"


def ns(t: float) -> int:
    """Run time `t` (s) on the hub's clock, in ns."""
    return round((ORIGIN + t) * 1e9)


def event(node: str, t: float, action: str = "req") -> dict:
    return {"t": t, "iota": node, "action": action, "index": None, "kind": "output", "value": None}


def write(path, host, messages, *, hub=False, offset=None, origin=ORIGIN, system="split", text=SYSTEM,
          cut_short=False, clock="real"):
    """A recording as a host launcher's recorder writes one: `messages` are (topic, log ns,
    publish ns, sequence, value), log times on the host's own clock."""
    sink = McapSink(path)
    run = {"host": host, "hub": hub, "origin": origin}
    if offset is not None:
        run["clock"] = {"offset": offset, "bound": 0.0002, "samples": 16, "measured_ns": ns(-1) - round(offset * 1e9)}
    sink.add_metadata("iotad.recording", {"format": FORMAT, "system": system, "clock": clock, "source": "traces",
                                          "writer": "iotad record", "time_unit": 1.0, "run": run})
    sink.attach("system.toml", "application/toml", text.encode())
    for topic, log_ns, publish_ns, sequence, value in messages:
        sink.write(sink.channel(topic, "t", {}), log_ns, publish_ns, sequence, packb(value))
    sink.flush()
    end = sink.size()
    sink.finish()
    if cut_short:  # what a killed recorder leaves: no summary, no footer
        os.truncate(path, end)
    return path


def vision(t: float, seq: int, on_hub: bool) -> tuple:
    """Vision's event at run time t: sent on the arm's clock, received 1 ms later by the arm's
    recorder (arm clock) or 2 ms later by the hub's (hub clock)."""
    sent = ns(t) + round(AHEAD * 1e9)
    received = ns(t) + 2 * MS if on_hub else ns(t) + round(AHEAD * 1e9) + MS
    return VISION, received, sent, seq, event("vision", t)


def scheduler(t: float, seq: int, received: int) -> tuple:
    return SCHEDULER, received, ns(t), seq, event("scheduler", t, "ack")


def heartbeat(t: float, received: int) -> tuple:
    """Vision's heartbeat: sent without an attachment, so each recorder stamps its own receipt as
    its publish time; its bytes (the node's t) are what is the same in both files."""
    return "iota/split/vision/@heartbeat", received, received, 0, {"t": t, "firings": 3, "queue": 0, "restarts": 0}


@pytest.fixture
def partitioned(tmp_path):
    """The arm cut off from the hub from t=2.5 to t=4.5: the hub's recording lacks vision's events
    at t=3 and t=4 (its recorder saw seq 4 after seq 1: a sequence gap), the arm's own has them."""
    hub = write(tmp_path / "split.mcap", "brain", [
        scheduler(1.03, 0, ns(1.03) + MS), vision(1.0, 0, True), vision(2.0, 1, True),
        scheduler(2.5, 1, ns(2.5) + MS), vision(5.0, 4, True), heartbeat(2.2, ns(2.2) + 2 * MS),
        (GAP_TOPIC, ns(5.0) + 2 * MS, ns(5.0) + 2 * MS, 0, {"key": VISION, "expected": 2, "got": 4, "missing": 2}),
        (GAP_TOPIC, ns(5.1), ns(5.1), 1, {"key": SCHEDULER, "expected": 2, "got": 3, "missing": 1}),
    ], hub=True)
    # the arm heard the scheduler's first event too (before the cut): on its own clock
    arm = write(tmp_path / "split.arm.mcap", "arm", [
        vision(1.0, 0, False), scheduler(1.03, 0, ns(1.03) + round(AHEAD * 1e9) + 3 * MS),
        vision(2.0, 1, False), heartbeat(2.2, ns(2.2) + round(AHEAD * 1e9) + MS), vision(3.0, 2, False),
        vision(4.0, 3, False), vision(5.0, 4, False),
    ], offset=-AHEAD)
    return hub, arm


def test_host_times_move_onto_the_hubs_clock_and_each_message_is_kept_once(partitioned, tmp_path):
    hub, arm = partitioned
    out = tmp_path / "merged.mcap"
    write_merged(merge([arm, hub]), out)
    merged = read_recording(out)
    traces = [(m.topic.split("/")[2], m.value["t"], m.log_time) for m in merged.messages if m.topic.endswith("@trace")]
    # on the hub's clock, vision's event at t=1.0 (received 1 ms after) comes before the
    # scheduler's at t=1.03; on the arm's raw clock it would come 20 ms after it
    assert [(node, t) for node, t, _ in traces] == [
        ("vision", 1.0), ("scheduler", 1.03), ("vision", 2.0), ("scheduler", 2.5), ("vision", 3.0),
        ("vision", 4.0), ("vision", 5.0)]
    # held by both files, kept once: the arm's own copy (1 ms after sending on the hub's
    # clock), not the hub's (2 ms); the scheduler's is the hub's own
    log = {(node, t): when for node, t, when in traces}
    assert log[("vision", 1.0)] == ns(1.0) + MS and log[("vision", 5.0)] == ns(5.0) + MS
    assert log[("scheduler", 1.03)] == ns(1.03) + MS
    # the sender's times are left as sent (the delivery check reads them on the sender's clock)
    assert {m.publish_time for m in merged.messages if m.topic == VISION} == \
        {ns(t) + round(AHEAD * 1e9) for t in (1.0, 2.0, 3.0, 4.0, 5.0)}
    beats = [m for m in merged.messages if m.topic.endswith("@heartbeat")]
    assert len(beats) == 1 and beats[0].log_time == ns(2.2) + MS, beats  # once, the arm's own
    assert merged.complete and merged.info["merged"] == ["split.mcap", "split.arm.mcap"]


def test_a_stretch_the_hub_missed_is_a_gap_naming_the_host_and_the_interval(partitioned, tmp_path):
    hub, arm = partitioned
    out = tmp_path / "merged.mcap"
    write_merged(merge([hub, arm]), out)
    merged = read_recording(out)
    gaps = [g for g in merged_gaps(merged) if g["host"] == "arm"]
    assert len(gaps) == 1, gaps
    gap = gaps[0]
    assert gap["events"] == 2 and "did not reach the hub's recording" in gap["reason"]
    assert gap["from_ns"] == ns(3.0) + MS and gap["to_ns"] == ns(4.0) + MS
    assert gap["from_t"] == pytest.approx(3.001) and gap["to_t"] == pytest.approx(4.001)
    # the hub recorder's gap in vision's events is filled by the arm's file: gone; the one in
    # the scheduler's, which no file fills, stays
    assert [(g["key"], g["expected"], g["got"]) for g in merged.gaps()] == [(SCHEDULER, 2, 3)]
    # the base host's recording was not given: the whole run is a gap of it
    base = [g for g in merged_gaps(merged) if g["host"] == "base"]
    assert len(base) == 1 and "no recording of this host was given" in base[0]["reason"]


def test_a_host_recording_begun_late_or_cut_short_is_marked(tmp_path):
    hub = write(tmp_path / "split.mcap", "brain", [
        vision(0.5, 0, True), vision(1.0, 1, True), vision(2.0, 2, True), vision(3.0, 3, True),
        scheduler(3.5, 0, ns(3.5) + MS)], hub=True)
    arm = write(tmp_path / "split.arm.mcap", "arm", [vision(1.0, 1, False), vision(2.0, 2, False)],
                offset=-AHEAD, cut_short=True)
    assert not read_recording(arm).complete
    merged = merge([hub, arm])
    arm_gaps = sorted((g for g in merged.gaps if g["host"] == "arm"), key=lambda g: g["from_ns"])
    assert [g["reason"].split(")")[0] for g in arm_gaps] == ["its recording (split.arm.mcap", "its recording (split.arm.mcap"]
    began, cut = arm_gaps
    assert "began after 1 event(s)" in began["reason"] and began["from_ns"] == ns(0.5) + 2 * MS
    assert began["to_ns"] == ns(1.0) + MS
    assert "cut short" in cut["reason"] and cut["from_ns"] == ns(2.0) + MS and cut["to_ns"] == ns(3.5) + MS
    assert cut["events"] == 1  # vision's t=3 event, which only the hub's recording holds
    # every event is there once, whichever file held it
    assert sorted(m.value["t"] for m in merged.recording.messages if m.topic == VISION) == [0.5, 1.0, 2.0, 3.0]


def restarted(t: float, host: str, after: str, file: str) -> tuple:
    """The `@launcher` event of a restarted recorder, as its launcher announces it once the new
    one listens (recorded in the new file): the file it goes on in, and how the last one ended."""
    value = {"event": "recorder", "node": None, "pid": 7, "code": None, "t_ns": ns(t), "host": host,
             "message": f"recorder: restarted (pid 9), recording continues in {file}; the gap since {after} ended "
                        "is lost", "file": file, "after": after, "ended": "killed by SIGKILL after 2.0 s"}
    return "iota/split/@launcher", ns(t), ns(t), 0, value


def test_the_hubs_recording_split_by_a_restarted_recorder_merges_with_the_restart_named(tmp_path):
    # the hub's recorder was killed after t=2 and its successor wrote split_1.mcap from t=3.5;
    # the arm's recorder kept recording vision's event at t=3, which the hub heard unrecorded
    first = write(tmp_path / "split.mcap", "brain", [vision(1.0, 0, True), scheduler(1.5, 0, ns(1.5) + MS),
                                                    vision(2.0, 1, True)], hub=True, cut_short=True)
    then = write(tmp_path / "split_1.mcap", "brain", [restarted(3.5, "brain", str(first), str(tmp_path / "split_1.mcap")),
                                                     vision(4.0, 3, True), scheduler(4.5, 1, ns(4.5) + MS)], hub=True)
    arm = write(tmp_path / "split.arm.mcap", "arm", [vision(t, k, False) for k, t in enumerate((1.0, 2.0, 3.0, 4.0))],
                offset=-AHEAD)
    merged = merge([then, arm, first])  # in any order: each host's files are ordered by their first message
    assert [s.name for s in merged.sources] == ["split.mcap", "split_1.mcap", "split.arm.mcap"]
    # every event of every file, once
    assert sorted(m.value["t"] for m in merged.recording.messages if m.topic == VISION) == [1.0, 2.0, 3.0, 4.0]
    assert sorted(m.value["t"] for m in merged.recording.messages if m.topic == SCHEDULER) == [1.5, 4.5]
    brain = [g for g in merged.gaps if g["host"] == "brain"]
    assert len(brain) == 1, merged.gaps
    gap = brain[0]
    assert gap["reason"] == ("its recorder was restarted: split.mcap was cut short (killed by SIGKILL after 2.0 s) "
                             "at t=2.002 s, and the recording goes on in split_1.mcap from t=3.500 s; no other "
                             "recording holds an event of its nodes in between")
    assert (gap["from_ns"], gap["to_ns"]) == (ns(2.0) + 2 * MS, ns(3.5))
    # vision's t=3 event reached no hub file: a gap of the arm's events at the hub, as for a cut
    assert [g["events"] for g in merged.gaps if g["host"] == "arm" and "did not reach the hub" in g["reason"]] == [1]


def test_trace_events_lost_while_the_hubs_recorder_was_down_are_counted_and_placed_in_the_trace(tmp_path):
    # the scheduler's events 2 and 3 happened while the hub's recorder was down: its successor
    # began with event 4 and could not know what it missed. Vision's event 2 at t=3 is lost at
    # the hub too, but the arm's recording holds it: not lost. A new process's numbers begin
    # again (the scheduler restarted as the recorder came back): a jump down is no gap.
    first = write(tmp_path / "split.mcap", "brain", [
        scheduler(1.0, 0, ns(1.0) + MS), vision(1.5, 0, True), scheduler(1.8, 1, ns(1.8) + MS),
        vision(2.0, 1, True)], hub=True, cut_short=True)
    then = write(tmp_path / "split_1.mcap", "brain", [
        restarted(3.5, "brain", str(first), str(tmp_path / "split_1.mcap")), scheduler(4.0, 4, ns(4.0) + MS),
        vision(4.2, 3, True), scheduler(4.5, 5, ns(4.5) + MS)], hub=True)
    arm = write(tmp_path / "split.arm.mcap", "arm", [vision(t, k, False) for k, t in enumerate((1.5, 2.0, 3.0, 4.2))],
                offset=-AHEAD)
    out = tmp_path / "merged.mcap"
    write_merged(merge([first, then, arm]), out)
    merged = read_recording(out)
    brain = [g for g in merged_gaps(merged) if g["host"] == "brain"]
    assert len(brain) == 1 and brain[0]["events"] == 2, brain
    assert brain[0]["reason"].endswith("; 2 event(s) of its nodes' traces no recording holds (their numbers jump "
                                       "across it)")
    assert [(g["key"], g["expected"], g["got"], g["missing"]) for g in merged.gaps()] == [(SCHEDULER, 2, 4, 2)]
    # the scheduler's trace knows where it lacks them, and why: check judges it up to there
    (gap,) = merged.trace_gaps("scheduler")
    assert (gap["position"], gap["missing"], gap["from_t"], gap["to_t"]) == (2, 2, 1.8, 4.0)
    assert gap["why"] == "its host's recorder was down between split.mcap and split_1.mcap"
    assert merged.trace_gaps("vision") == []

    # the same, but the scheduler's process restarted in between: its new numbers begin at 0
    again = write(tmp_path / "split_2.mcap", "brain", [
        restarted(3.5, "brain", str(first), str(tmp_path / "split_2.mcap")), scheduler(4.0, 0, ns(4.0) + MS)],
        hub=True)
    assert merge([first, again, arm]).recorder_gaps == 0


@pytest.mark.parametrize("case, message", [
    ("system", "recordings of different systems do not merge"),
    ("run", "are recordings of different runs of 'split'"),
    ("text", "hold different system files of 'split'"),
    ("virtual", "a virtual run's recording"),
    ("no run", "not a host's recording of a run spread over hosts"),
    ("one", "merge joins the recordings of two hosts or more"),
    ("same file", "a file is given twice"),
])
def test_recordings_that_do_not_belong_together_are_one_clear_error(tmp_path, case, message):
    hub = write(tmp_path / "split.mcap", "brain", [vision(1.0, 0, True)], hub=True)
    other = {
        "system": dict(system="other"), "run": dict(origin=ORIGIN + 60), "text": dict(text=SYSTEM + "\n# edited\n"),
        "virtual": dict(clock="virtual"), "no run": {}, "one": {}, "same file": {},
    }[case]
    arm = write(tmp_path / "split.arm.mcap", "arm", [vision(1.0, 0, False)], offset=-AHEAD, **other)
    files = [hub, arm]
    if case == "no run":  # a recording made by `iotad record` alone: it names no host
        sink = McapSink(tmp_path / "plain.mcap")
        sink.add_metadata("iotad.recording", {"format": FORMAT, "system": "split", "clock": "real"})
        sink.finish()
        files = [hub, tmp_path / "plain.mcap"]
    elif case == "one":
        files = [hub]
    elif case == "same file":
        files = [hub, tmp_path / "." / "split.mcap"]
    with pytest.raises(MergeError, match=message.replace("(", r"\(").replace(")", r"\)")):
        merge(files)


def iotad(*args):
    return subprocess.run([sys.executable, "-m", "iotad", *map(str, args)], capture_output=True, text=True, timeout=60)


def test_the_merge_command_writes_a_file_that_info_reads_and_refuses_bad_input(partitioned, tmp_path):
    hub, arm = partitioned
    out = tmp_path / "merged.mcap"
    done = iotad("merge", hub, arm, "-o", out)
    assert done.returncode == 0, done.stderr
    # 7 events and a heartbeat, once each, the scheduler's sequence gap and 2 host gaps
    assert "merged 2 recordings of split: 11 messages" in done.stdout, done.stdout
    assert "5 copies held twice kept once, 1 recorder sequence gap(s) left" in done.stdout
    assert "split.arm.mcap: host arm's recording, 7 messages, 6 kept; clock offset -50.000 ms +-0.200 ms" in done.stdout
    info = iotad("info", out)
    assert info.returncode == 0, info.stderr
    assert "merged from: split.mcap, split.arm.mcap; host gaps: 2" in info.stdout, info.stdout
    assert "host arm: t=3.001..4.001 s of the run: 2 event(s) of its nodes did not reach" in info.stdout
    # the merged file is no input to another merge; an existing output is kept without --force
    for args, error in (([out, arm, "-o", tmp_path / "again.mcap"], "already a merged recording"),
                        ([hub, arm, "-o", out], "a recording is already there"),
                        ([hub, arm, "-o", hub], "is one of the recordings being merged"),
                        ([hub, tmp_path, "-o", tmp_path / "x.mcap"], "is a directory"),
                        ([hub, __file__, "-o", tmp_path / "x.mcap"], "not an MCAP recording")):
        bad = iotad("merge", *args)
        assert bad.returncode != 0 and error in bad.stderr, (args, bad.stderr)
        assert "Traceback" not in bad.stderr
    assert iotad("merge", hub, arm, "-o", out, "--force").returncode == 0


def test_a_host_clock_measured_again_moves_later_times_by_the_newer_offset(tmp_path):
    """The offset at start is in the file's metadata; a later measurement (a `clock` launcher
    event of the host) moves every time recorded after it by the offset it found."""
    from iotad.recording.recorded_clock import to_hub

    hub = write(tmp_path / "split.mcap", "brain", [scheduler(1.0, 0, ns(1.0) + MS)], hub=True)
    later = ns(2.0) + 40 * MS  # on the arm's clock, when it measured again (at t=2 on the hub's)
    arm = write(tmp_path / "split.arm.mcap", "arm", [
        vision(1.0, 0, False),
        ("iota/split/@launcher", later, later, 0, {"event": "clock", "host": "arm", "t": 2.0, "offset": -0.04, "bound": 0.0003}),
        # the arm's clock was found to be 40 ms ahead from then on: sent at t=3 on the hub's clock
        (VISION, ns(3.0) + 40 * MS + MS, ns(3.0) + 40 * MS, 1, event("vision", 3.0)),
    ], offset=-AHEAD)
    clock = to_hub(read_recording(arm))
    assert [o.offset for o in clock.measured] == [-AHEAD, -0.04]
    assert clock(ns(1.0) + round(AHEAD * 1e9)) == ns(1.0) and clock(later + 1) == later + 1 - 40 * MS
    merged = merge([hub, arm])
    times = {m.value["t"]: m.log_time for m in merged.recording.messages if m.topic == VISION}
    assert times == {1.0: ns(1.0) + MS, 3.0: ns(3.0) + MS}


def test_an_offset_that_steps_back_keeps_the_host_files_own_order(tmp_path):
    """A later measurement found the arm's offset 9 ms smaller: its events of the next 9 ms, moved
    by it, would fall before the last ones moved by the offset before. The hub's time holds still
    until the arm's catches up, so they keep the arm file's order (they once swapped a bus log's
    inputs and outputs in the merge, and check judged its frame counter 8 frames ahead)."""
    from iotad.recording.recorded_clock import to_hub

    measured = ns(2.0) + 50 * MS
    steps = [ns(2.0) + 50 * MS + k * MS for k in range(1, 25)]  # every ms after it, on the arm's clock
    arm = write(tmp_path / "split.arm.mcap", "arm", [
        (VISION, ns(1.9) + 50 * MS, ns(1.9) + 50 * MS, 0, event("vision", 1.9)),
        (VISION, measured - MS, measured - MS, 1, event("vision", 1.999)),
        ("iota/split/@launcher", measured, measured, 0,
         {"event": "clock", "host": "arm", "t": 2.0, "offset": -0.059, "bound": 0.0002}),
        *[(VISION, at, at, 2 + k, event("vision", 2.0 + (k + 1) / 1000)) for k, at in enumerate(steps)],
    ], offset=-AHEAD)
    clock = to_hub(read_recording(arm))
    assert clock(measured - MS) == ns(2.0) - MS
    # the new offset holds from the host's time of the measurement (t=2 on the hub's, +59 ms on
    # the arm's), where the old one had reached t=2.009: held there until the new one passes it
    assert [(clock(at) - ns(2.0)) // MS for at in steps] == [*range(1, 9), *[9] * 10, *range(10, 16)]
    hub = write(tmp_path / "split.mcap", "brain", [scheduler(1.0, 0, ns(1.0) + MS)], hub=True)
    merged = merge([hub, arm])
    order = [m.value["t"] for m in merged.recording.messages if m.topic == VISION]
    assert order == sorted(order) and len(order) == 26
    times = [m.log_time for m in merged.recording.messages if m.topic == VISION]
    assert times == sorted(times)


def test_a_host_launcher_started_again_in_the_run_records_a_second_file_and_both_merge(tmp_path):
    """The arm's agent died and a new one took the arm's part again: its launcher recorded the
    rest to split.arm-2.mcap. Both files are the arm's; the stretch between them that only the
    hub's recording holds is a gap of the arm, and every event is there once."""
    hub = write(tmp_path / "split.mcap", "brain", [vision(t, k, True) for k, t in enumerate((1.0, 2.0, 3.0, 4.0))],
                hub=True)
    first = write(tmp_path / "split.arm.mcap", "arm", [vision(1.0, 0, False)], offset=-AHEAD)
    again = write(tmp_path / "split.arm-2.mcap", "arm", [vision(4.0, 3, False)], offset=-AHEAD)
    merged = merge([hub, first, again])
    assert sorted(m.value["t"] for m in merged.recording.messages if m.topic == VISION) == [1.0, 2.0, 3.0, 4.0]
    between = [g for g in merged.gaps if g["host"] == "arm"]
    assert len(between) == 1 and between[0]["events"] == 2, merged.gaps
    assert "between its recordings split.arm.mcap and split.arm-2.mcap" in between[0]["reason"]
    assert between[0]["from_ns"] == ns(2.0) + 2 * MS and between[0]["to_ns"] == ns(3.0) + 2 * MS


def test_an_earlier_process_numbers_fill_no_gap_of_a_later_one(tmp_path):
    # the scheduler ran 0..4, restarted (numbering from 0 again: 0, 1), then the hub's recorder
    # was killed; its successor began with the new process's event 5: 2, 3 and 4 of the new
    # process are lost, though the first process's own 2, 3 and 4 are in the first file
    first = write(tmp_path / "split.mcap", "brain", [
        *(scheduler(1.0 + k / 10, k, ns(1.0 + k / 10) + MS) for k in range(5)),
        scheduler(2.0, 0, ns(2.0) + MS), scheduler(2.1, 1, ns(2.1) + MS)], hub=True, cut_short=True)
    then = write(tmp_path / "split_1.mcap", "brain", [
        restarted(3.5, "brain", str(first), str(tmp_path / "split_1.mcap")), scheduler(4.0, 5, ns(4.0) + MS)], hub=True)
    arm = write(tmp_path / "split.arm.mcap", "arm", [vision(1.5, 0, False)], offset=-AHEAD)
    out = tmp_path / "merged.mcap"
    write_merged(merge([first, then, arm]), out)
    merged = read_recording(out)
    assert [(g["key"], g["expected"], g["got"], g["missing"]) for g in merged.gaps()] == [(SCHEDULER, 2, 5, 3)]
