"""The Figure 2 system run by `iotad run examples/figure2.toml` (one process per IOTA) and recorded
by the `iotad record` it starts: the recording checks, replays identical, and plots."""
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from launcher_helpers import free_port
from recorded_systems import check_of_a_real_run

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("fig2") / "figure2.mcap"
    run = subprocess.run([sys.executable, "-m", "iotad.cli", "run", str(ROOT / "examples/figure2.toml"),
                          "--until", "8", "--after-live", "--port", str(free_port()), "-o", str(out), "--plain"],
                         cwd=ROOT, capture_output=True, text=True, timeout=90)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return out


def test_recording_holds_the_system(recorded):
    recording = read_recording(recorded)
    assert recording.complete and recording.system == "figure2"
    assert {"scheduler", "vision", "manipulation"} <= set(recording.specs)
    assert recording.system_text and "[[node]]" in recording.system_text
    events = {e["event"] for e in recording.launcher_events()}
    assert {"start", "exit"} <= events
    acks = [m.value for m in recording.messages if m.topic.startswith("iota/figure2/scheduler/ack/")]
    assert {"ABORT", "COMMIT"} <= set(acks)
    assert recording.schema_of("iota/figure2/scheduler/ack/0").name == "ack"
    assert recording.gaps() == []


def test_check_passes(recorded):
    check_of_a_real_run(recorded)  # every message delivered as sent; a node late only under load


@pytest.mark.parametrize("node", ["scheduler", "vision", "manipulation"])
def test_replay_agrees(recorded, node):
    result = replay_node(read_recording(recorded), node, tolerance=0.01)
    assert result.ok, "\n".join(result.lines())
    assert len(result.recorded) > 0


def test_plot(recorded, tmp_path):
    assert main(["plot", str(recorded), "-o", str(tmp_path / "fig2.png")]) == 0


def test_trace_sourced_channels_hold_every_message_the_nodes_sent_and_saw(recorded):
    """`iotad run` records from the nodes' traces: each output on its key with the sender's
    sequence and send time, as many as the senders' traces say, and every message a node
    received is there with the attachment it arrived with (what a direct recording holds)."""
    recording = read_recording(recorded)
    assert recording.info["source"] == "traces"
    by_key: dict = {}
    for message in recording.messages:
        by_key.setdefault(message.topic, []).append(message)
    sent: dict = {}
    for event in recording.trace():
        if event["kind"] == "output":
            sent.setdefault(event["key"], []).append((event["seq"], event["send_ns"], event["value"]))
    assert {"iota/figure2/vision/req", "iota/figure2/scheduler/ack/0", "iota/figure2/scheduler/mdl_command"} <= set(sent)
    for key, outputs in sent.items():
        assert [(m.sequence, m.publish_time, m.value) for m in by_key[key]] == outputs, key
        assert all(m.log_time >= m.publish_time for m in by_key[key])
    received = [e for e in recording.trace() if e["kind"] == "input"]
    assert received
    for event in received:
        assert (event["seq"], event["send_ns"]) in {(m.sequence, m.publish_time) for m in by_key[event["key"]]}
    channel_keys = {k for k in by_key if not k.split("/")[-1].startswith("@") and not k.startswith("@")}
    assert channel_keys == set(sent)  # nothing from outside the nodes: every message explained
