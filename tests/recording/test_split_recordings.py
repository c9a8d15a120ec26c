"""Split recordings (`iotad record --max-size/--max-duration`): a set of numbered files, each a
whole recording, that every reading command takes as one recording; and a recorder killed with
SIGKILL in the middle of a set leaves the earlier files complete and the last one recoverable.
Real `iotad record` processes on loopback; every wait is on a condition (a file, a count)."""
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from iotad.cli import main
from iotad.node_host import wire
from iotad.node_host.transport import open_session
from iotad.recording.foxglove_mapping import topic_of
from iotad.recording.mcap_format import SET_METADATA
from iotad.recording.mcap_reader import read_recording, set_files
from launcher_helpers import free_port
from node_harness import wait_for

ROOT = Path(__file__).resolve().parents[2]
KEY = "iota/s/src/out"
PROBE = "iota/s/src/probe"  # published until every recorder hears the source; not compared


class Recorder:
    """`iotad record iota/s/** -o OUTPUT ...` listening on a port of its own; always stopped."""

    def __init__(self, output: Path, *extra: str):
        self.port, self.output = free_port(), output
        ready = output.with_suffix(".ready")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "iotad.cli", "record", "iota/s/**", "-o", str(output),
             "--listen", f"tcp/127.0.0.1:{self.port}", "--ready-file", str(ready), "--quiet", *extra],
            cwd=ROOT, stderr=subprocess.PIPE, text=True)
        wait_for(lambda: ready.exists() or self.proc.poll() is not None, 30, what="the recorder to subscribe")
        assert self.proc.poll() is None, self.proc.stderr.read()

    def stop(self, sig=signal.SIGINT) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            return self.proc.wait(30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait(10)


@pytest.fixture
def recorders():
    started: list[Recorder] = []

    def start(output: Path, *extra: str) -> Recorder:
        started.append(Recorder(output, *extra))
        return started[-1]

    yield start
    for recorder in started:
        recorder.stop(signal.SIGKILL)


class Source:
    """A publisher on KEY, connected to every recorder given, numbering its messages from 0."""

    def __init__(self, *recorders: Recorder):
        self.session = open_session(connect=[f"tcp/127.0.0.1:{r.port}" for r in recorders])
        self.publisher = self.session.declare_publisher(KEY, congestion_control=zenoh.CongestionControl.BLOCK)
        self.sent = 0
        # `matching` says "at least one": probe until every recorder has written a probe
        probe = self.session.declare_publisher(PROBE)
        deadline = time.monotonic() + 20
        while not all(count(r.output, PROBE) for r in recorders):
            assert time.monotonic() < deadline, "the recorders never heard the source"
            probe.put(wire.encode(None))
            time.sleep(0.05)
        probe.undeclare()

    def batch(self, count: int = 20) -> None:
        for _ in range(count):
            self.publisher.put(wire.encode(self.sent), attachment=wire.encode_attachment(self.sent, time.time_ns()))
            self.sent += 1

    def close(self) -> None:
        self.publisher.undeclare()
        self.session.close()


def members(output: Path) -> list[Path]:
    try:
        return set_files(output) if output.exists() else []
    except Exception:  # noqa: BLE001 - caught between the recorder's writes: look again
        return []


def count(output: Path, topic: str) -> int:
    try:
        return sum(1 for m in read_recording(output).messages if m.topic == topic)
    except Exception:  # noqa: BLE001 - a file being written
        return 0


def received(output: Path) -> int:
    return count(output, KEY)


def test_split_set_of_three_or_more_files_reads_back_as_the_unsplit_recording(tmp_path, recorders, capsys):
    split = recorders(tmp_path / "split.mcap", "--max-size", "1")  # every flush that wrote starts a new file
    whole = recorders(tmp_path / "whole.mcap")
    source = Source(split, whole)
    try:
        for _ in range(4):  # a batch, then wait for the next file: at least 4 files with messages
            before = len(members(split.output))
            source.batch()
            wait_for(lambda: len(members(split.output)) > before, 20, what=f"file {before + 1} of the set")
        wait_for(lambda: received(split.output) == source.sent and received(whole.output) == source.sent,
                 20, what="every message in both recordings")
    finally:
        source.close()
    assert split.stop() == 0 and whole.stop() == 0
    files = set_files(split.output)
    assert len(files) >= 3 and [f.name for f in files[:3]] == ["split_0.mcap", "split_1.mcap", "split_2.mcap"]
    for file in files:  # each whole on its own: footer, metadata, no set list
        alone = read_recording(file)
        assert alone.complete and alone.info["system"] == "s" and SET_METADATA not in alone.metadata
    assert sum(1 for f in files if received(f)) >= 3  # the messages are spread over the set
    one, unsplit = read_recording(split.output), read_recording(whole.output)
    assert one.complete and one.files == [str(f) for f in files]
    assert {k: v for k, v in one.topics().items() if k != PROBE} == \
        {k: v for k, v in unsplit.topics().items() if k != PROBE}
    assert [m.sequence for m in one.messages if m.topic == KEY] == list(range(source.sent))
    assert [m.value for m in one.messages if m.topic == KEY] == [m.value for m in unsplit.messages if m.topic == KEY]
    # the commands read the set as one recording
    capsys.readouterr()
    assert main(["info", str(split.output)]) == 0
    assert f"{KEY}" in capsys.readouterr().out
    assert main(["export", str(split.output), "--json", "-o", str(tmp_path / "json.mcap")]) == 0
    with open(tmp_path / "json.mcap", "rb") as stream:  # a JSON copy, for Foxglove: iotad's reader refuses it
        # on the topic `iotad view` shows the channel on (the shared Foxglove mapping)
        exported = sum(1 for _, channel, _ in make_reader(stream).iter_messages() if channel.topic == topic_of(KEY))
    assert exported == source.sent


def test_recorder_killed_mid_set_leaves_earlier_files_whole_and_the_last_recoverable(tmp_path, recorders, capsys):
    # files of 1.5 s: the kill lands in a file just begun (unless the machine stalls that long)
    recorder = recorders(tmp_path / "set.mcap", "--max-duration", "1.5")
    source = Source(recorder)
    try:
        before = len(members(recorder.output))
        while len([f for f in members(recorder.output) if received(f)]) < 3:
            source.batch()  # into the file in progress, then wait for the next one to begin
            wait_for(lambda: len(members(recorder.output)) > before, 20, what=f"file {before + 1} of the set")
            before = len(members(recorder.output))
        source.batch()  # into the file just begun, which the kill cuts
        wait_for(lambda: received(recorder.output) == source.sent, 20, what="the last batch in the file")
        assert recorder.stop(signal.SIGKILL) == -signal.SIGKILL
    finally:
        source.close()
    files = set_files(recorder.output)
    *earlier, last = files
    assert len(earlier) >= 2 and all(read_recording(f).complete for f in earlier)
    assert not read_recording(last).complete  # cut: no footer
    assert not read_recording(recorder.output).complete  # and so the set read as one
    # the set as it is still holds every message flushed before the kill
    assert [m.sequence for m in read_recording(recorder.output).messages if m.topic == KEY] == list(range(source.sent))
    fixed = tmp_path / "last.recovered.mcap"
    assert main(["recover", str(last), "-o", str(fixed)]) == 0
    assert read_recording(fixed).complete and received(fixed) == received(last)
    joined = tmp_path / "joined.mcap"  # the whole set recovered into one complete file
    assert main(["recover", str(recorder.output), "-o", str(joined)]) == 0
    out = read_recording(joined)
    assert out.complete and not out.files and SET_METADATA not in out.metadata
    assert [m.sequence for m in out.messages if m.topic == KEY] == list(range(source.sent))
    assert "was cut short" in capsys.readouterr().out


def test_a_set_with_another_runs_file_or_a_missing_last_file_is_never_read_as_whole(tmp_path, recorders, capsys):
    """Every member names its set and its place: a file of another run copied in, or members
    renamed over each other, are refused by name; a deleted last file makes the set INCOMPLETE
    (all three used to read as a complete recording that `iotad check` passed)."""
    import shutil

    sets = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        sets.append(recorders(tmp_path / name / "run.mcap", "--max-size", "1"))
    source = Source(*sets)
    try:
        for _ in range(3):
            before = [len(members(r.output)) for r in sets]
            source.batch()
            for r, n in zip(sets, before):
                wait_for(lambda r=r, n=n: len(members(r.output)) > n, 20, what="the next file of a set")
        wait_for(lambda: all(received(r.output) == source.sent for r in sets), 20, what="every message")
    finally:
        source.close()
    assert all(r.stop() == 0 for r in sets)
    names = [f.name for f in set_files(sets[0].output)]
    assert len(names) >= 3 and read_recording(sets[0].output).complete

    def variant(label: str) -> Path:
        folder = tmp_path / label
        shutil.copytree(tmp_path / "a", folder)
        return folder / "run.mcap"

    foreign = variant("foreign")
    shutil.copy(tmp_path / "b" / names[1], foreign.parent / names[1])
    with pytest.raises(Exception, match=rf"{names[1]} belongs to another split recording"):
        read_recording(foreign)
    swapped = variant("swapped")
    (swapped.parent / names[0]).rename(swapped.parent / "x")
    (swapped.parent / names[1]).rename(swapped.parent / names[0])
    (swapped.parent / "x").rename(swapped.parent / names[1])
    with pytest.raises(Exception, match=rf"{names[0]} is file 1 of its set, not file 0"):
        read_recording(swapped)
    cut = variant("cut")
    (cut.parent / names[-1]).unlink()
    recording = read_recording(cut)
    assert not recording.complete and f"{names[-1]}, the last file the set lists, is missing" in \
        recording.truncated_reason
    capsys.readouterr()
    main(["info", str(cut)])
    assert "the last file the set lists, is missing" in capsys.readouterr().out
    # a hole: a file before the last cut short. Read on across it, the trace would run on as if
    # nothing were missing (a check then blamed the nodes for windows that closed in the hole)
    holed = variant("holed")
    middle = holed.parent / names[1]
    with open(middle, "r+b") as file:
        file.truncate(middle.stat().st_size // 2)
    recording = read_recording(holed)
    assert not recording.complete and "a hole in the split recording: the set is read up to there" in \
        recording.truncated_reason and names[2] in recording.truncated_reason
    assert [Path(f).name for f in recording.files] == names[:2]
    up_to_hole = received(holed.parent / names[0]) + received(middle)
    assert received(holed) == up_to_hole < source.sent
    assert read_recording(holed.parent / names[2]).complete  # the file after the hole reads alone
    assert main(["info", str(foreign)]) == 2
    assert "belongs to another split recording" in capsys.readouterr().err


def test_a_split_recording_never_writes_over_a_file_that_is_there(tmp_path, recorders):
    """The set's numbered files go next to -o: `keep_1.mcap` of an earlier run (or the user's
    own) was written over in silence by the set's second file. A name that is taken is skipped
    (the set file lists its files by name); --force, which replaces the recording at -o,
    replaces its numbered files too."""
    earlier = tmp_path / "keep_1.mcap"
    earlier.write_bytes(b"an earlier run's recording")
    forced_folder = tmp_path / "forced"
    forced_folder.mkdir()
    (forced_folder / "keep_1.mcap").write_bytes(b"the set --force replaces")
    kept = recorders(tmp_path / "keep.mcap", "--max-size", "1")
    forced = recorders(forced_folder / "keep.mcap", "--max-size", "1", "--force")
    source = Source(kept, forced)
    try:
        for _ in range(3):
            before = [len(members(r.output)) for r in (kept, forced)]
            source.batch()
            for r, n in zip((kept, forced), before):
                wait_for(lambda r=r, n=n: len(members(r.output)) > n, 20, what="the next file of a set")
        wait_for(lambda: all(received(r.output) == source.sent for r in (kept, forced)), 20, what="every message")
    finally:
        source.close()
    assert kept.stop() == 0 and forced.stop() == 0
    assert earlier.read_bytes() == b"an earlier run's recording"
    names = [f.name for f in set_files(kept.output)]
    assert names[:3] == ["keep_0.mcap", "keep_1-2.mcap", "keep_2.mcap"], names
    recording = read_recording(kept.output)
    assert recording.complete and [m.sequence for m in recording.messages if m.topic == KEY] == list(range(source.sent))
    assert [f.name for f in set_files(forced.output)][:3] == ["keep_0.mcap", "keep_1.mcap", "keep_2.mcap"]
    assert read_recording(forced.output).complete
