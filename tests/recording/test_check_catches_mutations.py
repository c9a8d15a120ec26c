"""`iotad check` on the Figure 2 demo: the honest recording passes; hand-mutated ones are caught
with a message that names the event."""
from pathlib import Path

import pytest

from iotad.recording.conformance import check_implements, check_trace
from iotad.cli import main
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording, RecordedMessage
from iotad.recording.mcap_sink import McapSink
from requesters import Requester
from scheduler import Scheduler
from recorded_systems import find, mutate
from recorded_systems import figure2

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    # vision pauses 1.0 after an answer, so that no input masks a missing ack (see test below)
    path = tmp_path_factory.mktemp("rec") / "fig2.mcap"
    record_run(figure2(vision_pause=1.0), path, until=30)
    return path


def check(path, capsys):
    code = main(["check", str(path), "--node", "scheduler"])
    return code, capsys.readouterr().out


def test_honest_recording_passes(recorded, capsys):
    assert main(["check", str(recorded)]) == 0
    out = capsys.readouterr().out
    assert "every node conforms" in out and "ack[i](COMMIT)" in out  # the slack table


def test_ack_later_than_T(recorded, tmp_path, capsys):
    def late(events):
        k = find(events, action="ack", value="COMMIT", index=1)
        events[k] = dict(events[k], t=events[k]["t"] + 0.8)  # T = 0.5
        return events
    code, out = check(mutate(recorded, tmp_path / "m.mcap", "scheduler", late), capsys)
    assert code == 1
    assert "[late] output ack[1]=COMMIT at t=3.8 fired 0.3 after its window [3, 3.5] closed" in out


def test_commit_before_its_epoch(recorded, tmp_path, capsys):
    def early(events):
        k = find(events, action="commit", index=1)
        events[k] = dict(events[k], t=events[k]["t"] - 0.5)  # after epoch = 2.0
        return events
    code, out = check(mutate(recorded, tmp_path / "m.mcap", "scheduler", early), capsys)
    assert code == 1
    assert "[early] internal commit[1] at t=2.5 fired 0.5 before its window [3, 3] opened" in out


def test_missing_abort(recorded, tmp_path, capsys):
    def drop(events):
        del events[find(events, action="ack", value="ABORT", index=0)]
        return events
    code, out = check(mutate(recorded, tmp_path / "m.mcap", "scheduler", drop), capsys)
    assert code == 1
    assert "[expired] ack[0](ABORT) was enabled at t=1 and had to fire by t=1.5; it never fired" in out


def test_input_faster_than_its_switching_time(recorded, tmp_path, capsys):
    def extra(events):
        first = events[find(events, action="req", kind="input", index=0)]
        return events + [dict(first, t=first["t"] + 0.4)]  # switching time 1
    code, out = check(mutate(recorded, tmp_path / "m.mcap", "scheduler", extra), capsys)
    assert code == 1
    assert "[switching_time] input req[0]=" in out and "at t=0.4 came 0.4 after the previous one at t=0" in out


def test_output_value_the_spec_does_not_give(recorded, tmp_path, capsys):
    def wrong(events):
        k = find(events, action="ack", value="COMMIT", index=1)
        events[k] = dict(events[k], value="REJECT")
        return events
    code, out = check(mutate(recorded, tmp_path / "m.mcap", "scheduler", wrong), capsys)
    assert code == 1 and "[wrong_value] output ack[1]=REJECT at t=3" in out and "ack[1](COMMIT)=COMMIT" in out


def test_tolerance_absorbs_small_lateness(recorded, tmp_path, capsys):
    def slightly(events):
        # the commit and what it enables at the same instant come 4 ms late, as from a real process
        t = events[find(events, action="commit", index=1)]["t"]
        return [dict(e, t=e["t"] + 0.004) if e["t"] == t else e for e in events]
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", slightly)
    assert main(["check", str(path), "--node", "scheduler"]) == 1
    assert main(["check", str(path), "--node", "scheduler", "--tolerance", "0.01"]) == 0
    capsys.readouterr()


def test_implements_own_spec_and_not_another(recorded, capsys):
    recording = read_recording(recorded)
    scheduler_trace = recording.trace("scheduler")
    assert check_implements(Scheduler("scheduler", N=2, T=0.5), scheduler_trace).ok
    vision = recording.trace("vision")
    report = check_implements(Requester("vision", priority=1, epoch=3.0, timeout=4.0, start=0.5, pause=1.0,
                                        setpoint=0.2), vision)
    assert not report.ok and report.explained == 0
    assert "output req=" in report.lines()[0] and "at t=0" in report.lines()[0]
    assert any("may fire only in [0.5, 0.5]" in reason for reason in report.reasons)
    # the same through the command line, with the spec named by file
    spec = f"{Requester.__module__ and __import__('requesters').__file__}:Requester"
    assert main(["check", str(recorded), "--node", "vision", "--spec", spec, "--param", "priority=1",
                 "--param", "epoch=3.0", "--param", "timeout=4.0", "--param", "pause=1.0",
                 "--param", "setpoint=0.2"]) == 0
    assert main(["check", str(recorded), "--node", "vision", "--spec", spec, "--param", "priority=7"]) == 1
    out = capsys.readouterr().out
    assert "does not implement" in out and "cannot explain event #0" in out


def test_check_trace_api_reports_slack(recorded):
    recording = read_recording(recorded)
    report = check_trace(Scheduler("scheduler", N=2, T=0.5), recording.trace("scheduler"))
    assert report.ok and report.firings > 10
    assert report.slack["commit[i]"].after_open == 0 and report.slack["ack[i](COMMIT)"].before_close == 0.5


def test_bad_input_is_exit_2(recorded, tmp_path, capsys):
    assert main(["check", str(recorded), "--node", "nosuch"]) == 2
    assert main(["check", str(recorded), "--node", "vision", "--spec", str(tmp_path / "none.iota")]) == 2
    assert main(["check", str(recorded), "--spec", "x.py:Y"]) == 2
    err = capsys.readouterr().err
    assert err.count("iotad: error:") == 3 and "Traceback" not in err


def test_a_node_silent_for_the_whole_run_is_no_pass(tmp_path, capsys):
    # vision asks for the motors on its own: its first window closed long before the run's
    # recorded end (`iotad run --virtual` writes it) and never fired. With no event at all it
    # was "0 events, 0 problem(s)" and passed
    source = tmp_path / "fig2.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "20", "-o", str(source)]) == 0
    code = main(["check", str(mutate(source, tmp_path / "m.mcap", "vision", lambda events: [])), "--no-delivery"])
    out = capsys.readouterr().out
    assert code == 1
    assert "vision: 0 events" in out and "[expired] req" in out, out
    assert main(["check", str(tmp_path / "m.mcap"), "--node", "vision", "--no-delivery"]) == 1
    assert "[expired] req" in capsys.readouterr().out


def test_a_wrong_value_too_long_to_show_says_where_it_differs(tmp_path, capsys):
    # a CAN frame printed cut short looks the same recorded and expected: the message says which
    # field differs, and so does replay's
    source = tmp_path / "buggy.mcap"
    assert main(["run", str(ROOT / "examples" / "buggy.toml"), "--virtual", "--until", "3", "-o", str(source)]) == 0

    def flip(events):  # one frame of the motor's bursts (can_tx_burst: an instant's frames in one output)
        k = [j for j, e in enumerate(events) if e["action"] == "can_tx_burst" and e["kind"] == "output"][20]
        value = events[k]["value"][0]
        events[k] = dict(events[k], value=[dict(value, data=[value["data"][0] ^ 1] + value["data"][1:])]
                         + events[k]["value"][1:])
        flipped.append((value["data"][0] ^ 1, value["data"][0]))
        return events
    flipped = []
    path = mutate(source, tmp_path / "m.mcap", "motor", flip)
    capsys.readouterr()
    assert main(["check", str(path), "--node", "motor", "--no-delivery"]) == 1
    mine, spec = flipped[0]
    assert f"(recorded against the spec's: [0].data[0]: {mine} against {spec})" in capsys.readouterr().out
    assert main(["replay", str(path), "--node", "motor"]) == 1
    assert f"(recorded against replayed: [0].data[0]: {mine} against {spec})" in capsys.readouterr().out


def test_an_event_recorded_out_of_time_order_is_named_itself(recorded, tmp_path, capsys):
    # it was blamed on the event after it ("came -0.4 after the previous one, sooner than its
    # switching time"), and the moved event itself was not named
    def back(events):
        k = find(events, action="ack", value="COMMIT", index=1)
        moved = dict(events.pop(k), t=events[k - 1]["t"] - 0.4)
        events.insert(k, moved)
        return events
    recording = read_recording(recorded)
    events = back(recording.trace("scheduler"))
    report = check_trace(Scheduler("scheduler", T=0.5), events)
    [finding] = [f for f in report.findings if f.code == "out_of_order"]
    assert finding.message.startswith("output ack[1]=COMMIT at t=") and "goes back in time" in finding.message


def test_a_message_recorded_at_another_time_than_it_was_sent_is_said_so_once(tmp_path, capsys):
    # vision's second request moved by 1 ms in its own trace: the delivery check called the
    # receipt "duplicated" (of the first request, which had the same value) and the request "lost"
    source = tmp_path / "fig2.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "20", "-o", str(source)]) == 0

    def shift(events):
        k = [j for j, e in enumerate(events) if e["action"] == "req" and e["kind"] == "output"][1]
        events[k] = dict(events[k], t=events[k]["t"] + 1e-3)
        return events
    capsys.readouterr()
    assert main(["check", str(mutate(source, tmp_path / "m.mcap", "vision", shift))]) == 1
    out = capsys.readouterr().out
    assert "[duplicated]" not in out and "[lost]" not in out and "[unexplained]" not in out, out
    assert "[altered] vision.req -> scheduler.req[0]: output 1" in out and "was received at t=2.7: 1 ms from its time" in out
    assert "[altered] vision.req -> (wire): output 1" in out and "is on the wire at t=2.7: 1 ms from its time" in out
