"""A virtual run that stops while its bus is busy says so in its recording: the frames the modelled
bus still held at `--until` (on the wire, queued; or ended with their burst still to come) are
listed in the run's end (`iotad.can_at_end`), each with its station, the wire times it would have
had, and its state. `iotad check` judges them by it: a station's frame the list holds is cut at
the end (named with those times), one neither carried nor listed is lost; a frame that ended
before the run did counts as carried. Format 1 says nothing of them: in flight, not judged."""
from pathlib import Path

from iotad.cli import main
from iotad.recording.bursts import wire_frames
from iotad.recording.mcap_format import CAN_AT_END
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink

ROOT = Path(__file__).resolve().parents[2]


def slow_arm(tmp_path: Path) -> Path:
    """examples/arm_can.toml on a 50 kbit/s bus: its frames queue for seconds."""
    text = (ROOT / "examples" / "arm_can.toml").read_text()
    text = text.replace("arm_trajectory.py", str(ROOT / "examples" / "arm_trajectory.py"))
    system = tmp_path / "slow.toml"
    system.write_text(text.replace("bitrate = 1000000", "bitrate = 50000", 1))
    return system


def run(tmp_path: Path, *options: str) -> Path:
    out = tmp_path / f"slow{''.join(options)}.mcap"
    assert main(["run", str(slow_arm(tmp_path)), "--virtual", "--until", "1.95", "-o", str(out), *options]) == 0
    return out


def with_metadata(source: Path, target: Path, name: str, value: dict) -> Path:
    """A copy of `source` whose metadata `name` is `value` (its messages as the file holds them)."""
    recording = read_recording(source)
    sink = McapSink(target)
    for attachment in recording.attachments:
        sink.attach(attachment.name, attachment.media_type, attachment.data)
    for key, data in recording.metadata.items():
        if key != name:
            sink.writer.add_metadata(key, data)
    sink.add_metadata(name, value)
    for message in sorted((m for m in recording.messages if not m.derived), key=lambda m: m.log_time):
        sink.write(sink.channel(message.topic, "any", {}), message.log_time, message.publish_time, message.sequence,
                   message.data)
    sink.finish()
    return target


def test_the_frames_a_busy_bus_held_at_the_end_are_listed_and_judged_by_it(tmp_path, capsys):
    path = run(tmp_path)
    recording = read_recording(path)
    held = recording.can_at_end["arm_bus"]
    assert recording.can_at_end_t == 1.95 and len(held) > 20  # a queue of more than a second
    states = [f["state"] for f in held]
    assert states.count("on the wire") <= 1 and states.count("queued") > 20
    # in bus order after the frames its bursts recorded, back to back, each one frame time long
    carried = wire_frames(recording, "arm_bus")
    assert held[0]["order"] == len(carried)
    assert [f["order"] for f in held] == list(range(len(carried), len(carried) + len(held)))
    assert all(b["start"] == a["end"] for a, b in zip(held, held[1:]))
    assert all(f["end"] > 1.95 for f in held if f["state"] != "ended")
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    cut = [line for line in out.splitlines() if "cut at the end:" in line and "-> (bus)" in line]
    assert cut and "queued when the run ended at t=1.95" in out
    assert "in flight (queued or on the bus)" not in out

    # a frame the bus neither carried nor held: the list says so, the check finds it lost
    queued = next(f for f in held if f["state"] == "queued")
    dropped = with_metadata(path, tmp_path / "dropped.mcap", CAN_AT_END,
                            {"t": 1.95, "buses": {"arm_bus": [f for f in held if f is not queued]}})
    capsys.readouterr()
    assert main(["check", str(dropped)]) == 1
    out = capsys.readouterr().out
    lost = [line for line in out.splitlines() if "[lost]" in line]
    assert len(lost) == 1 and f"frame 0x{queued['id']:03X}" in lost[0] and "neither carried it nor held it" in lost[0]


def test_format_1_says_nothing_of_them_and_leaves_them_not_judged(tmp_path, capsys):
    path = run(tmp_path, "--format", "1")
    assert read_recording(path).can_at_end == {}
    capsys.readouterr()
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "in flight (queued or on the bus) when the run ended" in out and "cut at the end" not in out
