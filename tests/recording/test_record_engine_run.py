"""Recordings written from an in-process Engine run (the sink) read back with the mcap library."""
import json
from pathlib import Path

from mcap.reader import make_reader

from iotad.cli import main
from iotad.kernel.compose import Composite
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import SCHEMA_ENCODING
from iotad.recording.mcap_reader import read_recording
from requesters import Requester
from scheduler import Scheduler
from recorded_systems import figure2


def test_summary_indexes_schemas_and_counts(tmp_path):
    out = tmp_path / "fig2.mcap"
    engine = record_run(figure2(), out, until=30)
    outputs = [e for e in engine.trace if e["kind"] == "output"]
    with open(out, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        stats = summary.statistics
        # every event on its node's @trace, every output also on its channel key
        assert stats.message_count == len(engine.trace) + len(outputs)
        topics = {c.id: c.topic for c in summary.channels.values()}
        counts = {topics[k]: v for k, v in stats.channel_message_counts.items()}
        assert counts["iota/figure2/scheduler/@trace"] == sum(1 for e in engine.trace if e["iota"] == "figure2/scheduler")
        assert counts["iota/figure2/scheduler/ack/0"] == sum(
            1 for e in outputs if e["action"] == "ack" and e["index"] == 0)
        assert all(c.message_encoding == "msgpack" for c in summary.channels.values())
        schemas = {s.name: s for s in summary.schemas.values()}
        assert {"ack", "mdlReq", "mode", "iotad.trace_event"} <= set(schemas)
        assert all(s.encoding == SCHEMA_ENCODING for s in schemas.values())
        assert json.loads(schemas["ack"].data)["enum"] == ["COMMIT", "ABORT", "REJECT"]
        assert summary.chunk_indexes and all(ci.message_index_offsets for ci in summary.chunk_indexes)
        names = {a.name for a in summary.attachment_indexes}
        assert {"spec/scheduler.json", "spec/vision.json", "spec/manipulation.json", "system.json"} <= names
        assert {m.name for m in summary.metadata_indexes} >= {"iotad.recording"}
        # the message indexes let a seeking reader pick one topic
        acks = [m for _, _, m in reader.iter_messages(topics=["iota/figure2/scheduler/ack/0"])]
        assert len(acks) == counts["iota/figure2/scheduler/ack/0"]


def test_reader_round_trip_and_info(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    engine = record_run(figure2(), out, until=30)
    recording = read_recording(out)
    assert recording.complete
    assert recording.nodes() == ["manipulation", "scheduler", "vision"]
    trace = recording.trace("scheduler")
    expected = [dict(e, iota="scheduler") for e in engine.trace if e["iota"] == "figure2/scheduler"]
    assert [{k: e[k] for k in ("t", "iota", "action", "index", "kind", "value")} for e in trace] == expected
    spec = recording.specs["scheduler"]
    assert spec["params"] == {"N": 2, "T": 0.5} and "class Scheduler" in spec["text"]
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "scheduler" in text and "iota/figure2/scheduler/ack/0" in text and "violations: 0" in text


def test_bad_files_are_one_line_errors(tmp_path, capsys):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    assert main(["info", str(bad)]) == 2
    assert main(["info", str(tmp_path / "missing.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("iotad: error:") for line in err)
    assert "Traceback" not in "".join(err)


def test_export_json_for_foxglove(tmp_path):
    out, exported = tmp_path / "fig2.mcap", tmp_path / "fig2.json.mcap"
    record_run(figure2(), out, until=30)
    assert main(["export", str(out), "-o", str(exported), "--json"]) == 0
    with open(exported, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert {c.message_encoding for c in summary.channels.values() if c.topic != "/log"} == {"json"}
        seen = {}
        for schema, channel, message in reader.iter_messages():
            if channel.topic == "/log":  # foxglove.Log (protobuf): the acks and violations
                continue
            value = json.loads(message.data)
            assert isinstance(value, dict)  # Foxglove shows fields of objects
            seen.setdefault(channel.topic, value)
    # the channels on the topics `iotad view` shows (foxglove_mapping), the traces on their keys
    assert seen["/scheduler/ack/0"] == {"value": "ABORT"}
    assert seen["/vision/req"]["priority"] == 1
    assert "iota/figure2/scheduler/ack/0" not in seen and "iota/figure2/scheduler/@trace" in seen
    assert summary.statistics.message_count == len(read_recording(out).messages) + summary.statistics.channel_message_counts[
        next(i for i, c in summary.channels.items() if c.topic == "/log")]


def test_the_tools_say_a_json_export_is_not_a_recording_they_read(tmp_path, capsys):
    out, exported = tmp_path / "fig2.mcap", tmp_path / "fig2.json.mcap"
    record_run(figure2(), out, until=10)
    assert main(["export", str(out), "-o", str(exported), "--json"]) == 0
    capsys.readouterr()
    for command in (["info"], ["check"], ["plot", "-o", str(tmp_path / "p.png")]):
        assert main([command[0], str(exported), *command[1:]]) == 2
        err = capsys.readouterr().err
        assert "a JSON copy for Foxglove ('iotad export --json'); iotad's tools read the msgpack recording" in err
        assert "damaged" not in err and "Traceback" not in err


def test_plot_draws_a_png(tmp_path):
    out, png = tmp_path / "fig2.mcap", tmp_path / "fig2.png"
    record_run(figure2(), out, until=30)
    assert main(["plot", str(out), "-o", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    from iotad.recording.timeline_plot import requester_names, timeline
    recording = read_recording(out)
    assert requester_names(recording, "scheduler") == {0: "vision", 1: "manipulation"}
    holds = timeline(recording, "scheduler")["holds"]
    assert holds[0][:2] == (0, 0.0) and holds[0][3] == "pre-empted"
    assert Path(png).exists()


def test_a_title_is_text_even_with_dollar_signs(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    record_run(figure2(), out, until=10)
    picture = tmp_path / "cost.png"
    assert main(["plot", str(out), "-o", str(picture), "--title", "cost: $5 per 2^$"]) == 0  # was mathtext: a crash
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
