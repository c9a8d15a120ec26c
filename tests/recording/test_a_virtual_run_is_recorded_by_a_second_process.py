"""`iotad run --virtual -o` on a machine with two cores or more: the recording is written by a
second process (`iotad.recording.writer_process`). The file is the one the run's own process
would write; a writer that dies, an engine that dies, a file that cannot be written and a Ctrl-C
each end in a clear message and a recording that says what happened."""
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.virtual import virtual_run
from iotad.recording.engine_sink import recording_header
from iotad.recording.mcap_reader import read_recording
from iotad.recording.writer_process import CUT_SHORT, RecordingProcess, WriterFailed

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "figure2.toml"


def record(out: Path, *more: str) -> int:
    return main(["run", str(FIGURE2), "--virtual", "--until", "30", "-o", str(out), "--plain", *more])


def contents(path: Path):
    recording = read_recording(path)
    messages = [(m.topic, m.log_time, m.publish_time, m.sequence, m.data) for m in recording.messages]
    attachments = [(a.name, a.media_type, a.data) for a in recording.attachments]
    return recording, messages, attachments


def test_the_second_process_writes_the_file_the_run_would_write_itself(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(virtual_run, "cores", lambda: 1)
    assert record(tmp_path / "inline.mcap") == 0
    assert "written by a second process" not in capsys.readouterr().out
    monkeypatch.setattr(virtual_run, "cores", lambda: 2)
    monkeypatch.setattr("iotad.recording.writer_process.BATCH", 8)  # many batches, one cut mid-way
    assert record(tmp_path / "process.mcap") == 0
    assert "written by a second process" in capsys.readouterr().out
    inline, inline_messages, inline_attachments = contents(tmp_path / "inline.mcap")
    process, process_messages, process_attachments = contents(tmp_path / "process.mcap")
    assert len(inline_messages) == 62  # the whole Figure 2 exchange: requests, acks, commands
    assert process_messages == inline_messages
    assert process_attachments == inline_attachments
    assert process.metadata == inline.metadata and process.run_end == 30.0 and process.complete
    assert main(["check", str(tmp_path / "process.mcap")]) == 0


def test_a_writer_that_dies_is_a_clear_error_and_the_file_keeps_what_it_wrote(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(virtual_run, "cores", lambda: 2)
    monkeypatch.setattr("iotad.recording.writer_process.BATCH", 8)  # batches go out during the run
    handed = RecordingProcess.__call__
    seen = []

    def killing(self, event):
        seen.append(event)
        if len(seen) == 40:  # the writer dies mid-run (a full disk, an OOM kill, a kill -9)
            os.kill(self._process.pid, signal.SIGKILL)
            self._process.wait()
        handed(self, event)

    monkeypatch.setattr(RecordingProcess, "__call__", killing)
    out = tmp_path / "killed.mcap"
    assert record(out) == 2
    err = capsys.readouterr().err
    assert "iotad: error: the recording's writer process stopped: it said nothing (killed by signal 9); " \
           f"{out} holds what it wrote before" in err
    assert "Traceback" not in err
    monkeypatch.undo()
    # the file is not taken for a whole one (a killed writer loses the chunk it held, as a
    # killed run's own process would)
    assert main(["info", str(out)]) == 0
    assert f"{out}: INCOMPLETE (no footer" in capsys.readouterr().out


def test_a_writer_killed_as_soon_as_it_opened_its_file_leaves_a_recording_not_an_empty_file(tmp_path, capsys):
    # under load the writer may die before it wrote its first chunk: the file's header is on
    # disk before it says `ready`, so what is left is an incomplete recording
    out = tmp_path / "early.mcap"
    writer = RecordingProcess()
    writer.open(out)
    os.kill(writer._process.pid, signal.SIGKILL)
    writer._process.wait()
    writer.close()
    assert main(["info", str(out)]) == 0
    assert f"{out}: INCOMPLETE (no footer" in capsys.readouterr().out


def test_an_engine_that_dies_leaves_a_whole_file_that_says_the_run_was_cut_short(tmp_path):
    from recorded_systems import figure2
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine

    out = tmp_path / "orphan.mcap"
    writer = RecordingProcess()
    root = figure2()
    writer.open(out)
    writer.begin(recording_header(root, "figure2"))
    engine = Engine(root, VirtualClock(), sinks=[writer])
    engine.run(10)
    writer._send()  # everything handed over, then the engine's side ends without `finish`
    assert writer.close() == 0  # what a killed engine's process leaves: the pipe's end
    recording = read_recording(out)
    assert recording.complete  # summary and footer: every tool reads it
    assert recording.run_error == f"{CUT_SHORT} at t={engine.trace[-1]['t']:g} s"
    assert len(recording.trace("scheduler")) == sum(1 for e in engine.trace if e["iota"] == "figure2/scheduler")
    assert main(["check", str(out)]) == 1


def test_a_file_the_writer_cannot_create_is_refused_before_the_run(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(virtual_run, "cores", lambda: 2)
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        if os.access(locked, os.W_OK):
            # root writes anywhere: a path under a file stands in
            target = tmp_path / "a-file" / "run.mcap"
            (tmp_path / "a-file").write_text("")
        else:
            target = locked / "run.mcap"
        assert record(target) == 2
        err = capsys.readouterr().err
        assert f"-o {target}" in err and "Traceback" not in err
        assert not target.exists()
    finally:
        locked.chmod(0o700)
    with pytest.raises(WriterFailed, match=r"^cannot write: No such file or directory$"):
        writer = RecordingProcess()
        writer.open("/proc/no/such.mcap")


def test_a_writer_never_opened_exits_quietly():
    writer = RecordingProcess()
    assert writer.close() == 0


def test_the_writer_is_not_a_command_of_its_own():
    done = subprocess.run([sys.executable, "-m", "iotad.recording.writer_process", "out.mcap"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "takes no arguments" in done.stderr


def test_ctrl_c_stops_a_virtual_run_between_steps_and_the_recording_is_whole(tmp_path):
    out = tmp_path / "stopped.mcap"
    run = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(ROOT / "examples" / "buggy.toml"), "--virtual",
                            "--until", "100000", "-o", str(out), "--plain"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        said = []
        while not said or "x real time" not in said[-1]:  # the first progress line: the run is going
            said.append(run.stderr.readline())
            assert said[-1], "".join(said)  # it ended before saying so
        run.send_signal(signal.SIGINT)
        stdout, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    assert run.returncode == 0, stderr
    stderr = "".join(said) + stderr
    assert "stopped by Ctrl-C at t = " in stderr and "Traceback" not in stderr
    stopped_at = float(stderr.split("stopped by Ctrl-C at t = ")[1].split()[0])
    assert 0 < stopped_at < 100000
    recording = read_recording(out)
    assert recording.complete and recording.run_error == ""
    assert recording.run_end == pytest.approx(stopped_at, abs=1e-3)  # every node ran until then
    assert f"recording: {out}" in stdout


def test_a_writer_that_cannot_be_started_leaves_the_recording_to_the_run_itself(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(virtual_run, "cores", lambda: 2)
    monkeypatch.setattr(sys, "executable", str(tmp_path / "no-python-here"))
    out = tmp_path / "inline.mcap"
    assert record(out) == 0
    said = capsys.readouterr().out
    assert f"recording: {out}  (iotad info" in said  # not "written by a second process"
    assert read_recording(out).run_end == 30.0


def test_a_writer_dead_before_it_opened_the_file_says_so(tmp_path):
    writer = RecordingProcess()
    os.kill(writer._process.pid, signal.SIGKILL)
    writer._process.wait()
    with pytest.raises(WriterFailed, match=r"^the recording's writer process stopped before it opened the file "
                                           r"\(killed by signal 9\)$"):
        writer.open(tmp_path / "never-written.mcap")
    assert not (tmp_path / "never-written.mcap").exists()


def second_ctrl_c():
    """A first Ctrl-C (a real SIGINT: the run takes it as a request) and, at once, the second
    one's KeyboardInterrupt, right here."""
    os.kill(os.getpid(), signal.SIGINT)
    while signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pass  # Python runs the handler between bytecodes: it has, once it restored the default one
    raise KeyboardInterrupt


@pytest.mark.parametrize("where", ["a node's firing", "the middle of a write to the writer"])
def test_a_second_ctrl_c_exits_130_and_the_recording_says_the_run_broke_off(tmp_path, monkeypatch, capsys, where):
    """A second Ctrl-C raises at once, wherever the run is: in a firing (an output recorded and not
    yet delivered, maybe), or half-way through a batch on its way to the writer. Either way the
    run exits 130 and the recording is whole but marked, so `iotad check` does not pass it."""
    import iotad.recording.writer_process as writer_process

    monkeypatch.setattr(virtual_run, "cores", lambda: 2)
    monkeypatch.setattr(writer_process, "BATCH", 8)
    if where == "a node's firing":
        handed = RecordingProcess.__call__
        seen = []

        def interrupting(self, event):
            seen.append(event)
            if len(seen) == 30:
                second_ctrl_c()
            handed(self, event)

        monkeypatch.setattr(RecordingProcess, "__call__", interrupting)
    else:
        writes = []
        real_write = os.write

        def half_then_interrupt(fd, data):
            writes.append(len(data))
            if len(writes) == 4:  # the open command, the header, a batch, then half of the next
                real_write(fd, bytes(data[:len(data) // 2]))
                second_ctrl_c()
            return real_write(fd, data)

        monkeypatch.setattr(writer_process.os, "write", half_then_interrupt)
    out = tmp_path / "hard.mcap"
    assert record(out) == 130
    assert "stopped hard by a second Ctrl-C at t = " in capsys.readouterr().err
    monkeypatch.undo()
    recording = read_recording(out)
    assert recording.complete and recording.run_end is None
    expected = CUT_SHORT if where != "a node's firing" else "stopped hard by a second Ctrl-C, possibly in the middle"
    assert recording.run_error.startswith(expected)
    assert main(["check", str(out)]) == 1
    assert "BROKE OFF" in capsys.readouterr().out


def test_a_stalled_writer_does_not_hold_a_ctrl_c_and_is_stopped(tmp_path, monkeypatch):
    """The writer stops reading (SIGSTOP here; a hung disk alike): the engine blocks once the
    pipe is full, a Ctrl-C still gets through, and the writer is given HARD_STOP_WAIT to finish
    before it is killed."""
    import iotad.recording.writer_process as writer_process
    from recorded_systems import figure2

    monkeypatch.setattr(writer_process, "HARD_STOP_WAIT", 0.5)
    writer = RecordingProcess()
    writer.open(tmp_path / "stalled.mcap")
    writer.begin(recording_header(figure2(), "figure2"))
    os.kill(writer._process.pid, signal.SIGSTOP)
    previous = signal.signal(signal.SIGALRM, signal.default_int_handler)  # the "Ctrl-C", in 1 s
    signal.setitimer(signal.ITIMER_REAL, 1.0)
    try:
        with pytest.raises(KeyboardInterrupt):
            for k in range(10_000):  # 10 MB: ten times what the pipe holds
                # a value of its own each (a batch writes an object it holds twice once)
                writer({"t": 0.0, "iota": "figure2/vision", "action": "req", "index": None, "kind": "output",
                        "value": {"padding": f"{k:05d}" + "x" * 1000}})
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert writer.torn
    assert writer.close() == -signal.SIGKILL  # still stopped after the wait: killed


def test_events_marshal_cannot_batch_are_written_as_the_run_itself_writes_them(tmp_path):
    """Events go to the writer in batches (marshal); a batch holding a value marshal does not
    write (a float or int of a subclass, as numpy's) goes as msgpack maps. Either way the file
    holds what the engine's own process writes, in order."""
    import enum

    import numpy

    from iotad.recording.engine_sink import EngineRecorder
    from iotad.recording.mcap_sink import McapSink
    from recorded_systems import figure2

    class Level(enum.IntEnum):
        HIGH = 3

    def event(k: int, value) -> dict:
        return {"t": k * 0.25, "iota": "figure2/vision", "action": "req", "index": None, "kind": "output",
                "value": value}

    events = [event(0, {"w": 1.5, "k": 2}), event(1, {"w": numpy.float64(0.1), "k": 3}),
              event(2, [1, (2, 3), None, True]), event(3, {"w": 2.5, "k": Level.HIGH}), event(4, "plain")]
    header = recording_header(figure2(), "figure2")
    inline = McapSink(tmp_path / "inline.mcap")
    recorder = EngineRecorder.from_header(inline, header)
    for one in events:
        recorder(dict(one))
    inline.finish()
    writer = RecordingProcess()
    writer.open(tmp_path / "process.mcap")
    writer.begin(header)
    for one in events[:3]:  # a batch with a numpy float, then one with an IntEnum
        writer(dict(one))
    writer.add_metadata("iotad.test", {"between": "batches"})
    for one in events[3:]:
        writer(dict(one))
    writer.finish()
    _, inline_messages, _ = contents(tmp_path / "inline.mcap")
    process, process_messages, _ = contents(tmp_path / "process.mcap")
    assert len(inline_messages) == 10  # each event's trace message and its output's
    assert process_messages == inline_messages
    assert process.metadata["iotad.test"] == {"between": "batches"}
