"""`iotad check` cross-checks senders, wire and receivers: real recordings of examples/figure2.toml
(one in virtual time, one of real processes over zenoh) changed only on the wire or in a
receiver's account are caught, and the problem is named with its link; the clean copies pass."""
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import stop_launcher
from recorded_systems import check_of_a_real_run
from wire_tamper import index_of, rewrite, with_value

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "figure2.toml"
S = "iota/figure2/scheduler"


@pytest.fixture(scope="module")
def virtual(tmp_path_factory):
    path = tmp_path_factory.mktemp("virtual") / "fig2.mcap"
    assert main(["run", str(FIGURE2), "--virtual", "--until", "20", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    """Three processes and a recorder over zenoh on loopback (the launcher picks a free port)."""
    directory = tmp_path_factory.mktemp("real")
    path, out = directory / "fig2.mcap", directory / "run.out"
    with open(out, "wb") as sink:
        run = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(FIGURE2), "--until", "8", "--after-live",
                                "--port", "0", "--plain", "-o", str(path), "--log-dir", str(directory / "logs")],
                               stdout=sink, stderr=subprocess.STDOUT, cwd=ROOT, start_new_session=True)
    try:
        assert run.wait(90) == 0, out.read_text()[-3000:]
    finally:
        stop_launcher(run)  # also on failure: the launcher and its nodes
    return path


@pytest.fixture(params=["virtual", "real"])
def recorded(request):
    return request.getfixturevalue(request.param)


def check(path, capsys, *extra):
    code = main(["check", str(path), *extra])
    return code, capsys.readouterr().out


def verdict(out):
    """What check's last line found wrong: set() for a pass, else e.g. {"conformance", "delivery"}."""
    last = out.strip().splitlines()[-1]
    return set(last.split("PROBLEMS FOUND (")[1].split(")")[0].split(" and ")) if "PROBLEMS FOUND (" in last else set()


def conformance_of(path, capsys):
    """check's verdict on every node against its spec alone. A real run's processes share a loaded
    machine, where a firing a few ms past its window is a true conformance finding, but not what
    these tests are about: each judges delivery, and holds conformance to what the clean copy had."""
    code, out = check(path, capsys, "--no-delivery")
    return code, verdict(out)


def receiver_input(value):
    return value.get("kind") == "input" and value.get("action") == "ack"


# each: (how the copy differs, the finding's code, the link it names)
def value_changed(messages):
    k = index_of(messages, S + "/ack/0")
    messages[k] = with_value(messages[k], "COMMIT" if messages[k].value != "COMMIT" else "ABORT")
    return messages


def dropped(messages):
    del messages[index_of(messages, S + "/mdl_command")]
    return messages


def duplicated(messages):
    k = index_of(messages, S + "/ack/0")
    messages.insert(k + 1, messages[k])
    return messages


def injected(messages):
    k = index_of(messages, S + "/ack/0")
    messages.insert(k + 1, replace(messages[k], sequence=4242, publish_time=messages[k].publish_time + 1000,
                                   data=packb("REJECT")))
    return messages


def input_removed(messages):
    del messages[index_of(messages, "iota/figure2/vision/@trace", receiver_input)]
    return messages


def input_altered(messages):
    k = index_of(messages, "iota/figure2/vision/@trace", receiver_input)
    event = messages[k].value
    messages[k] = with_value(messages[k], dict(event, value="COMMIT" if event["value"] != "COMMIT" else "ABORT"))
    return messages


def input_received_twice(messages):
    k = index_of(messages, "iota/figure2/vision/@trace", receiver_input)
    event = messages[k].value
    messages.insert(k + 1, replace(messages[k], log_time=messages[k].log_time + 1,
                                   data=packb(dict(event, t=event["t"] + 1e-6))))
    return messages


MUTATIONS = [
    (value_changed, "altered", "scheduler.ack[0] -> (wire)"),
    (dropped, "lost", "scheduler.mdl_command -> (wire)"),
    (duplicated, "duplicated", "scheduler.ack[0] -> (wire)"),
    (injected, "unexplained", "scheduler.ack[0] -> (wire)"),
    (input_removed, "lost", "scheduler.ack[0] -> vision.ack"),
    (input_altered, "altered", "scheduler.ack[0] -> vision.ack"),
    (input_received_twice, "duplicated", "scheduler.ack[0] -> vision.ack"),
]


def test_the_clean_recording_passes_with_every_message_delivered(recorded, virtual, capsys):
    if recorded == virtual:
        code, out = check(recorded, capsys)
        assert code == 0, out
    else:
        out = check_of_a_real_run(recorded)
    report = check_delivery(read_recording(recorded), tolerance=0.01)
    assert report.ok and not [f for f in report.findings if f.problem], "\n".join(report.lines())
    links = {link.label: link for link in report.links}
    ack = links["scheduler.ack[0] -> vision.ack"]
    assert ack.sent == ack.delivered >= 2 and ack.problems == 0
    assert links["scheduler.mdl_command -> (wire)"].delivered >= 2
    p50, p99, most = ack.latency()
    assert 0 <= p50 <= p99 <= most


@pytest.mark.parametrize("mutation, code, link", MUTATIONS, ids=[m[0].__name__ for m in MUTATIONS])
def test_a_mutation_on_the_wire_or_at_the_receiver_is_caught_and_named(recorded, tmp_path, capsys,
                                                                       mutation, code, link):
    path = rewrite(recorded, tmp_path / "mutated.mcap", mutation)
    exit_code, out = check(path, capsys)
    assert exit_code == 1
    assert f"[{code}] {link}:" in out
    assert "delivery" in verdict(out), out
    # the wire alone: every node's own trace conforms as it did in the clean copy; a receiver's
    # account changed may not
    if "input" not in mutation.__name__:
        assert conformance_of(path, capsys) == conformance_of(recorded, capsys)
    report = check_delivery(read_recording(path), tolerance=0.01)
    assert [f.code for f in report.findings if f.problem] == [code]
    assert any(line.strip().startswith(link) for line in report.table())
    assert getattr(next(x for x in report.links if x.label == link), code) == 1


def test_the_issue_cases_ack1_commit_to_abort_and_a_missing_mdl_command(virtual, tmp_path, capsys):
    def both(messages):
        k = index_of(messages, S + "/ack/1", lambda v: v == "COMMIT")
        messages[k] = with_value(messages[k], "ABORT")
        return dropped(messages)
    code, out = check(rewrite(virtual, tmp_path / "m.mcap", both), capsys)
    assert code == 1
    assert "[altered] scheduler.ack[1] -> (wire): output 0: scheduler sent COMMIT, the wire carried ABORT" in out
    assert "[lost] scheduler.mdl_command -> (wire): output 0" in out and "the wire holds no such message" in out


def test_a_rejection_the_receiver_recorded_is_no_loss(real, tmp_path, capsys):
    def rejected(messages):
        k = index_of(messages, "iota/figure2/vision/@trace", receiver_input)
        event = messages[k].value
        messages[k] = with_value(messages[k], {
            "t": event["t"], "iota": event["iota"], "action": "ack", "index": None, "kind": "violation",
            "value": {"violation": "bad_value", "message": "input ack: not an ack; rejected"}})
        return messages
    path = rewrite(real, tmp_path / "m.mcap", rejected)
    report = check_delivery(read_recording(path), tolerance=0.01)
    link = next(x for x in report.links if x.label == "scheduler.ack[0] -> vision.ack")
    assert (link.rejected, link.lost) == (1, 0) and report.ok
    code, out = check(path, capsys)
    assert code == 1 and "PROBLEMS FOUND (conformance)" in out  # the rejection itself is a finding


def test_a_rejection_that_names_its_message_takes_that_message_whenever_it_was_recorded(real, tmp_path):
    """A node host's refusal carries the refused message's key, seq and send_ns: it is matched to
    exactly that claim, even when its time does not say which (here 5 s after it was sent)."""
    def refused_late(messages):
        k = index_of(messages, "iota/figure2/vision/@trace", receiver_input)
        event = messages[k].value
        messages[k] = with_value(messages[k], {
            "t": event["t"] + 5.0, "iota": event["iota"], "action": "ack", "index": None, "kind": "violation",
            "value": {"violation": "bad_value", "message": "input ack: not an ack; rejected"},
            "key": event["key"], "seq": event["seq"], "send_ns": event["send_ns"]})
        return messages
    report = check_delivery(read_recording(rewrite(real, tmp_path / "m.mcap", refused_late)), tolerance=0.01)
    link = next(x for x in report.links if x.label == "scheduler.ack[0] -> vision.ack")
    assert (link.rejected, link.lost) == (1, 0) and report.ok


def test_no_delivery_skips_the_cross_check_and_node_limits_it(virtual, tmp_path, capsys):
    path = rewrite(virtual, tmp_path / "m.mcap", dropped)
    assert check(path, capsys, "--no-delivery")[0] == 0
    code, out = check(path, capsys, "--node", "vision")
    assert code == 0 and "scheduler.mdl_command" not in out and "scheduler.ack[0] -> vision.ack" in out
    assert check(path, capsys, "--node", "scheduler")[0] == 1


def test_a_run_that_ends_while_a_message_is_in_flight_is_no_false_alarm(real, tmp_path, capsys):
    """The recording as if the run had stopped just after the scheduler published its last ack to
    vision: vision's receipt (and all it did after) never happened. Not judged, and said so."""
    def cut(messages):
        # every node's account up to the instant of the send (node clocks share the launcher's
        # origin); the wire and the launcher's events up to the message's own arrival
        claim = messages[index_of(messages, S + "/@trace", lambda v: v.get("action") == "ack" and
                                  v.get("index") == 0 and v.get("kind") == "output", nth=-1)].value
        end = messages[index_of(messages, S + "/ack/0", lambda v: True, nth=-1)].log_time
        def traced(m):
            return m.topic.endswith(("/@trace", "/@heartbeat"))
        # an output another node claimed by then was published by then: keep its wire copy too,
        # however late the recorder got it (a run cannot end between a send and its claim)
        claimed = {m.value.get("send_ns") for m in messages
                   if m.topic.endswith("/@trace") and m.value["t"] <= claim["t"] and m.value.get("kind") == "output"}
        def kept(m):
            if traced(m):
                return m.value["t"] <= claim["t"]
            return m.log_time <= end or m.publish_time in claimed
        return [m for m in messages if kept(m)]
    path = rewrite(real, tmp_path / "cut.mcap", cut)
    code, out = check(path, capsys)
    assert "[not judged] scheduler.ack[0] -> vision.ack:" in out and "in flight when the run ended" in out
    assert "1 not judged (in flight at the end" in out
    assert "delivery" not in verdict(out), out
    assert (code, verdict(out)) == conformance_of(path, capsys), out  # only what conformance found, if anything
