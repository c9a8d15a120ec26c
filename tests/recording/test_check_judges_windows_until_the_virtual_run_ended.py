"""A virtual run records how far its engine ran (every node ran to there). A window that closed
before then and never fired is a missed deadline even if it was the node's last obligation:
the check used to judge windows only up to the node's last recorded event, so a recording
missing a node's final firings passed."""
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink

ROOT = Path(__file__).resolve().parents[2]


def without_the_schedulers_last_firing(source: Path, target: Path) -> dict:
    """A copy of `source` without the scheduler's messages at the time of its last output."""
    recording = read_recording(source)
    last = [e for e in recording.trace("scheduler") if e["kind"] == "output"][-1]
    at = round(last["t"] * 1e9)
    sink = McapSink(target)
    for item in recording.attachments:
        sink.attach(item.name, item.media_type, item.data)
    for name, fields in recording.metadata.items():
        sink.writer.add_metadata(name, fields)
    for message in recording.messages:
        if message.log_time == at and message.topic.startswith("iota/figure2/scheduler/"):
            continue
        sink.write(sink.channel(message.topic, "any", {}), message.log_time, message.publish_time, message.sequence,
                   message.data)
    sink.finish()
    return last


def test_a_nodes_missing_last_firing_is_an_expired_window(tmp_path, capsys):
    whole = tmp_path / "fig2.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "20", "-o", str(whole)]) == 0
    assert read_recording(whole).run_end == 20.0
    capsys.readouterr()
    assert main(["check", str(whole)]) == 0
    edited = tmp_path / "edited.mcap"
    last = without_the_schedulers_last_firing(whole, edited)
    assert (last["action"], last["value"]) == ("ack", "COMMIT")
    capsys.readouterr()
    assert main(["check", str(edited), "--no-delivery"]) == 1
    assert f"[expired] commit[0] was enabled at" in capsys.readouterr().out
