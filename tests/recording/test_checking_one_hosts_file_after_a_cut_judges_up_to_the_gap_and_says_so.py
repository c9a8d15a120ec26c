"""`iotad check` of the hub's recording alone after a cut longer than zenoh's lease: the cut-off
host's nodes sent events the hub never heard (its recorder saw their sequence numbers jump and
noted a gap; the launcher recorded the host lost, then back). Each of those nodes is judged up to
the gap, and the report says where the gap is, how many events it lacks and why (`host arm lost`),
and that what follows is not judged: never the wrong values and late firings a spec replayed
across the missing events finds (its counter stuck where the recording lost it). Messages sent to
such a node while the hub could not hear it are not judged either, never `lost`. The verdict is no
pass: the merge of every host's recording holds the rest.

The hub's file is built by hand, as a hub's recorder writes one, from a virtual run of the
system: a pulse on each host feeding a sink on the other (as in
tests/hosts/test_a_partition_longer_than_the_lease_heals_and_both_sides_recorded_it.py, which
checks a real one end to end)."""
import pytest

from iotad.cli import main
from iotad.node_host import wire
from iotad.kernel.compose import Composite
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import FORMAT, GAP_TOPIC, packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from namespaces import hosts_header
from system_iotas import FreeSink, Pulse

ORIGIN = 1_700_000_000.0
CUT = (3.0, 7.0)    # s of the run: arm's events strictly inside it never reached the hub's recorder
LOST, BACK = 5.5, 8.0  # the hub's launcher: host arm lost (its nodes down), then back
ARM = ("beat", "far")
SYSTEM = hosts_header("long", "10.0.0.1", 7447, "brain", "arm", "10.0.0.2") + """

[[node]]
name = "tick"
host = "brain"
python = "system_iotas.py:Pulse"
params = { period = 0.5 }
[[node]]
name = "near"
host = "brain"
python = "system_iotas.py:FreeSink"
[[node]]
name = "beat"
host = "arm"
python = "system_iotas.py:Pulse"
params = { period = 0.5 }
[[node]]
name = "far"
host = "arm"
python = "system_iotas.py:FreeSink"

[[bind]]
from = "tick.out"
to = "far.inp"
[[bind]]
from = "beat.out"
to = "near.inp"
"""


def ns(t: float) -> int:
    return round((ORIGIN + t) * 1e9)


def hubs_file(tmp_path, cut=CUT, lost=True):
    """The hub's recording of 12 s: every node's trace as a node host publishes it (a start
    record, then each event; outputs and inputs with the message's key, seq and send time), each
    output on its key, all received 1 ms after; arm's events inside `cut` left out, with the
    recorder's note of each sequence gap that left, and (`lost`) the launcher's `down` and
    `host_back`."""
    virtual = tmp_path / "virtual.mcap"
    record_run(Composite("long", Pulse("tick", period=0.5), FreeSink("near"), Pulse("beat", period=0.5),
                         FreeSink("far"), bind=[("tick.out", "far.inp"), ("beat.out", "near.inp")]),
               virtual, until=12)
    ran = read_recording(virtual)
    messages = []  # (topic, log ns, publish ns, sequence, value)
    sent = {}  # the sending node -> (its output key, the seq of its next message)
    senders = {"far": "tick", "near": "beat"}
    for node in ("tick", "beat", "near", "far"):
        trace = wire.trace_key("long", node)
        messages.append((trace, ns(0) + 1_000_000, ns(0), 0, wire.start_event(0.0, node, ORIGIN, 100 + len(messages))))
        heard, expected = True, 1
        events = [m.value for m in ran.messages if m.topic == trace]
        if node == "near":  # beat's outputs of the cut never reached it
            events = [e for e in events if not cut[0] < e["t"] < cut[1]]
        for seq, event in enumerate(events, start=1):
            t = event["t"]
            if event["kind"] == "output":
                key = wire.channel_key("long", node, "out", None)
                event.update(key=key, seq=seq - 1, send_ns=ns(t))
            else:  # as it came, from the sender's output at the same instant
                source = senders[node]
                event.update(key=wire.channel_key("long", source, "out", None), seq=event["value"],
                             send_ns=ns(t))
            if node in ARM and cut[0] < t < cut[1]:
                heard = False  # sent into the closed links: the hub's recorder never got it
                continue
            received = ns(t) + 1_000_000
            if not heard:
                messages.append((GAP_TOPIC, received, received, 0,
                                 {"key": trace, "expected": expected, "got": seq, "missing": seq - expected}))
                heard = True
            expected = seq + 1
            messages.append((trace, received, ns(t), seq, event))
            if event["kind"] == "output":
                messages.append((event["key"], received, ns(t), event["seq"], event["value"]))
    launcher = wire.launcher_key("long")
    for node in ARM if lost else ():
        messages.append((launcher, ns(LOST), ns(LOST), 0, {"event": "down", "node": node, "host": "arm", "pid": None,
                                                          "code": None, "t_ns": ns(LOST), "message": "host arm lost"}))
    messages += [(launcher, ns(BACK), ns(BACK), 0,
                  {"event": "host_back", "node": None, "host": "arm", "pid": 1, "code": None, "t_ns": ns(BACK),
                   "message": "host arm: back; its nodes ran on while it was cut off (beat, far)", "resumed": True})
                 ] if lost else []
    path = tmp_path / "long.mcap"
    sink = McapSink(path)
    sink.add_metadata("iotad.recording", {"format": FORMAT, "system": "long", "clock": "real", "source": "traces",
                                          "writer": "iotad run", "time_unit": 1.0,
                                          "run": {"host": "brain", "hub": True, "origin": ORIGIN}})
    sink.attach("system.toml", "application/toml", SYSTEM.encode())
    for node, spec in ran.specs.items():
        sink.add_spec(node, dict(spec, origin=ORIGIN), ns(0))
    for topic, log_ns, publish_ns, sequence, value in sorted(messages, key=lambda m: m[1]):
        sink.write(sink.channel(topic, "t", {}), log_ns, publish_ns, sequence, packb(value))
    sink.finish()
    return path


def check(path, capsys, *options):
    code = main(["check", str(path), "--all", *options])
    return code, capsys.readouterr().out


@pytest.fixture(scope="module")
def hub_file(tmp_path_factory):
    return hubs_file(tmp_path_factory.mktemp("cut"))


def test_a_node_of_the_cut_host_is_judged_up_to_the_gap_and_the_report_says_why(hub_file, capsys):
    code, out = check(hub_file, capsys, "--no-delivery")
    # nothing the nodes did is found wrong: before the fix, beat's first output after the gap
    # (n=13) was `wrong_value` against the spec's n=6, and every later one wrong too
    assert "[wrong_value]" not in out and "[late]" not in out and "[expired]" not in out, out
    lines = out.splitlines()
    beat = next(line for line in lines if line.startswith("beat: "))
    # judged: its 6 outputs before the cut (t=0.5..3); not judged: the 11 after it (t=7..12)
    assert beat == ("beat: 6 events, 6 firings checked, 0 problem(s); JUDGED ONLY UP TO A GAP in its trace "
                    "(11 event(s) after it not judged)"), out
    assert ("  GAP t=3..7: 7 event(s) of its trace are not in this recording (host arm lost: its nodes down at "
            "t=5.5, back at t=8); the 11 event(s) recorded after the gap (this run of its process) are not "
            "judged, since the state of its spec after the missing events is unknown") in lines, out
    assert ("  the recording of its own host holds what this one lacks: join every host's recording with "
            "'iotad merge' and check the merged file") in lines, out
    assert any(line.startswith("far: 6 events, 0 firings checked, 0 problem(s); JUDGED ONLY UP TO A GAP")
               for line in lines), out
    # the hub's own nodes, heard all along: judged whole, nothing said
    assert "tick: 24 events, 24 firings checked, 0 problem(s)" in lines, out
    assert "near: 17 events, 0 firings checked, 0 problem(s)" in lines, out
    assert out.count("  GAP t=") == 2, out
    # no pass: what beat and far did after the gap is not judged here
    assert code == 1
    assert lines[-1] == "check: PROBLEMS FOUND (beat, far judged only up to a gap in the trace) (tolerance 0.01)", out


def test_messages_sent_to_a_node_the_hub_could_not_hear_are_not_judged_lost(hub_file, capsys):
    code, out = check(hub_file, capsys)
    row = next(line for line in out.splitlines() if line.lstrip().startswith("tick.out -> far.inp"))
    # tick's 7 outputs inside the cut (t=3.5..6.5), sent while far's trace misses events the hub
    # never heard: far may have taken them then. Before the fix: 7 lost.
    assert row.split()[3:10] == ["24", "17", "0", "0", "0", "0", "0"], row  # sent, delivered, lost...
    assert row.split()[10] == "7", row  # not judged
    assert ("note: t=3.5 [not judged] tick.out -> far.inp: #6: sent while far's trace misses events this "
            "recording never heard (t=3..7: host arm lost: its nodes down at t=5.5, back at t=8): it may have "
            "taken it then") in out, out
    assert "[lost]" not in out, out
    assert out.splitlines()[-1] == ("check: PROBLEMS FOUND (beat, far judged only up to a gap in the trace) "
                                    "(tolerance 0.01)"), out


def test_without_the_gap_every_node_is_judged_whole(tmp_path, capsys):
    # the same recording with nothing cut: the check passes as before, no gap said
    code, out = check(hubs_file(tmp_path, cut=(100.0, 100.0)), capsys)
    assert code == 0, out
    assert "GAP" not in out and "JUDGED ONLY" not in out, out
    assert "beat: 24 events, 24 firings checked, 0 problem(s)" in out.splitlines(), out


def test_replay_goes_up_to_the_gap_and_says_so(hub_file, capsys):
    code = main(["replay", str(hub_file), "--node", "beat"])
    out = capsys.readouterr().out
    # before the fix: "replay diverges at output event #6: the replay never produced output out=13 at t=7"
    assert code == 0, out
    assert out.splitlines() == [
        "beat: replay agrees: 6 output events, every value computed again, each firing at its recorded time",
        "  GAP t=3..7: 7 event(s) of its trace are not in this recording (host arm lost: its nodes down at t=5.5, "
        "back at t=8); replayed up to the gap, the 11 event(s) recorded after it not"], out


def test_a_gap_with_no_host_lost_is_said_as_the_recorders_and_judged_the_same(tmp_path, capsys):
    # the recorder missed the events (it fell behind) and no host was lost: said as such
    code, out = check(hubs_file(tmp_path, lost=False), capsys, "--no-delivery")
    assert code == 1 and "[wrong_value]" not in out, out
    assert ("  GAP t=3..7: 7 event(s) of its trace are not in this recording (its sequence numbers jumped: the "
            "recorder never got them); the 11 event(s) recorded after the gap") in out, out
