"""A node whose process was restarted has one engine start per run on its @trace: `iotad check`
and `iotad replay` take each run from its own start and the spec's initial state (the new
process had no memory of the old one), and say when it restarted. A real-time recording that
holds no start of a node (an `iotad record` attached mid-run) is NOT CHECKED, not misjudged."""
from iotad.cli import main
from iotad.node_host import wire
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from recorded_systems import figure2, mutate

KILLED_AT, RESTARTED_AT, END = 4.5, 6.0, 14.0


def restarted_recording(tmp_path):
    """Figure 2 recorded in virtual time; the scheduler's trace then made two runs of its
    process: the first cut at KILLED_AT, a second (a fresh scheduler) started at RESTARTED_AT."""
    first = tmp_path / "first.mcap"
    record_run(figure2(), first, until=END)
    recorded = [e for e in read_recording(first).trace("scheduler")]
    iota = recorded[0]["iota"]
    engine = Engine(figure2(), VirtualClock(RESTARTED_AT))
    engine.run(END)
    second = [dict(e, iota=iota) for e in engine.trace if e["iota"].endswith("/scheduler")]

    def two_runs(events):
        start = lambda t: {"t": t, "iota": iota, "action": "@start", "index": None,  # noqa: E731
                           "kind": wire.START_KIND, "value": {"wall": 0.0, "pid": 1}}
        # sorted by t by mutate: the start record goes first at its instant (a stable sort)
        return ([start(0.0)] + [e for e in events if e["t"] < KILLED_AT]
                + [start(RESTARTED_AT)] + second)
    return mutate(first, tmp_path / "restarted.mcap", "scheduler", two_runs), second


def test_check_takes_each_run_from_its_own_start(tmp_path, capsys):
    path, second = restarted_recording(tmp_path)
    assert any(e["kind"] == "output" for e in second)  # the second run did something to judge
    assert main(["check", str(path), "--node", "scheduler", "--no-delivery"]) == 0
    out = capsys.readouterr().out
    assert "scheduler: " in out and " 0 problem(s)" in out
    assert f"restarted at t={RESTARTED_AT:g}: each run of its process is checked from its own start" in out


def test_replay_takes_each_run_from_its_own_start(tmp_path):
    path, second = restarted_recording(tmp_path)
    result = replay_node(read_recording(path), "scheduler", tolerance=1e-9)
    assert result.ok, "\n".join(result.lines())
    assert [e["t"] for e in result.replayed if e["t"] >= RESTARTED_AT] == \
        [e["t"] for e in second if e["kind"] == "output"]


def test_a_real_time_recording_without_a_node_s_start_is_not_checked(tmp_path, capsys):
    path = tmp_path / "fig2.mcap"
    record_run(figure2(), path, until=END)
    late = mutate(path, tmp_path / "late.mcap", "scheduler", lambda events: [e for e in events if e["t"] > 3.0])
    recording = read_recording(late)
    # as `iotad record` attached to a running system writes it: a real clock, no start records
    info = dict(recording.metadata["iotad.recording"], clock='"real"')
    rewritten = tmp_path / "late-real.mcap"
    from iotad.recording.mcap_sink import McapSink
    sink = McapSink(rewritten)
    for item in recording.attachments:
        sink.attach(item.name, item.media_type, item.data)
    sink.writer.add_metadata("iotad.recording", info)
    for message in recording.messages:
        sink.write(sink.channel(message.topic, "any", {}), message.log_time, message.publish_time,
                   message.sequence, message.data)
    sink.finish()
    assert main(["check", str(rewritten), "--no-delivery"]) == 1
    out = capsys.readouterr().out
    assert "scheduler: NOT CHECKED: the recording holds no start of its engine" in out
    assert "PROBLEMS FOUND (3 node(s) not checked)" in out


def without_second_start(tmp_path, launcher: bool):
    """The restarted recording as it reads when the new process's start record never reached
    the recorder (its first @trace burst lost); with `launcher`, the launcher's events of both
    processes are there, as in every `iotad run` recording."""
    path, second = restarted_recording(tmp_path)
    lost = mutate(path, tmp_path / "lost.mcap", "scheduler",
                  lambda events: [e for e in events if not (e["kind"] == wire.START_KIND and e["t"] > 0)])
    recording = read_recording(lost)
    from iotad.recording.mcap_format import packb
    from iotad.recording.mcap_sink import McapSink
    out = tmp_path / f"lost-{launcher}.mcap"
    sink = McapSink(out)
    for item in recording.attachments:
        sink.attach(item.name, item.media_type, item.data)
    for name, data in recording.metadata.items():
        sink.writer.add_metadata(name, data)
    messages = [(m.topic, m.log_time, m.data) for m in recording.messages]
    if launcher:
        key = wire.launcher_key(recording.system)
        for event, pid, t in (("start", 1, 0.0), ("live", 1, 0.0), ("exit", 1, KILLED_AT),
                              ("restart", 2, RESTARTED_AT - 0.2), ("live", 2, RESTARTED_AT)):
            ns = int(t * 1e9)
            messages.append((key, ns, packb({"event": event, "node": "scheduler", "pid": pid, "code": None,
                                             "t_ns": ns, "restarts": int(pid == 2)})))
    for k, (topic, log_time, data) in enumerate(sorted(messages, key=lambda m: m[1])):
        sink.write(sink.channel(topic, "any", {}), log_time, log_time, k, data)
    sink.finish()
    return out, second


def test_a_lost_start_record_is_made_from_the_launchers_events(tmp_path, capsys):
    path, second = without_second_start(tmp_path, launcher=True)
    starts = [e for e in read_recording(path).process_trace("scheduler") if e["kind"] == wire.START_KIND]
    assert [(e["t"], e["value"]["pid"], e["value"].get("from")) for e in starts] == [
        (0.0, 1, None), (RESTARTED_AT, 2, "launcher")]
    assert main(["check", str(path), "--node", "scheduler", "--no-delivery"]) == 0
    out = capsys.readouterr().out
    assert f"restarted at t={RESTARTED_AT:g}: each run of its process is checked from its own start" in out
    result = replay_node(read_recording(path), "scheduler", tolerance=1e-9)
    assert result.ok, "\n".join(result.lines())


def test_without_the_launchers_events_the_two_processes_read_as_one_run(tmp_path, capsys):
    path, _ = without_second_start(tmp_path, launcher=False)
    assert main(["check", str(path), "--node", "scheduler", "--no-delivery"]) == 1  # misjudged as one run
    assert "restarted at" not in capsys.readouterr().out
