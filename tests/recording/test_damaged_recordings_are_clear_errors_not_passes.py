"""A damaged recording is bad input: every reader says which message or attachment is damaged,
in one line with exit status 2, never an internal error; and `iotad check` never passes what it
could not check (a node without a readable spec, a recording cut short)."""
import json
import math

import pytest

from iotad.cli import main
from iotad.kernel.trace_jsonl import dumps, read
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink
from recorded_systems import COMPOSITE, figure2, rewrite

READERS = [["info"], ["check"], ["replay", "--node", "scheduler"], ["export", "--json", "-o", "{out}"]]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "fig2.mcap"
    record_run(figure2(), path, until=30)
    return path


def first_trace_event(change):
    """A payload rewrite of the scheduler's first trace event."""
    def data(topic, k, payload):
        if topic.endswith("scheduler/@trace") and k == 0:
            return change(payload)
        return payload
    return data


def run(args, tmp_path, capsys):
    status = main([a.replace("{out}", str(tmp_path / "out.mcap")) for a in args])
    captured = capsys.readouterr()
    return status, captured.err.strip().splitlines()


@pytest.mark.parametrize("reader", READERS, ids=lambda r: r[0])
@pytest.mark.parametrize("damage, says", [
    (lambda payload: b"\xc1\xc1garbage", "its payload is not msgpack"),
    (lambda payload: b"", "its payload is not msgpack"),
    (lambda payload: packb({"t": "x", "iota": "scheduler", "action": "req", "index": 0, "kind": "input",
                            "value": None}), "its time t is 'x', not a finite number"),
    (lambda payload: packb({"t": 1.0, "iota": "scheduler", "index": 0, "kind": "input", "value": None}),
     "its action is None, not a string"),
    (lambda payload: packb({"t": 1.0, "iota": "scheduler", "action": "req", "index": 0, "kind": "violation",
                            "value": "oops"}), "a violation whose value is 'oops', not a map"),
], ids=["garbage", "empty", "t-not-a-number", "no-action", "violation-not-a-map"])
def test_a_damaged_trace_message_is_named_in_one_line(recorded, tmp_path, capsys, reader, damage, says):
    path = rewrite(recorded, tmp_path / "damaged.mcap", data=first_trace_event(damage))
    status, err = run([reader[0], str(path), *reader[1:]], tmp_path, capsys)
    if reader[0] == "export" and "not msgpack" not in says:
        assert status == 0  # export copies what it cannot read as a trace event: only bytes matter
        return
    assert status == 2, err
    assert len(err) == 1 and err[0].startswith("iotad: error: message #0 on iota/figure2/scheduler/@trace"), err
    assert says in err[0] and "the recording is damaged" in err[0]


def _break_spec(node, change):
    def broken(name, data):
        if name != f"spec/{node}.json":
            return data
        spec = json.loads(data)
        spec["text"] = change(spec["text"])
        return json.dumps(spec).encode()
    return broken


def test_a_stored_spec_that_no_longer_builds_is_named(recorded, tmp_path, capsys):
    # Python: the requester's and scheduler's stored source
    path = rewrite(recorded, tmp_path / "spec.mcap",
                   attachment=_break_spec("scheduler", lambda text: text.replace("class Scheduler", "class Scheduler $", 1)))
    # check says it of that node and judges the others; asked for that node alone, or to replay it,
    # it is the one error
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out.splitlines()
    said = [line for line in out if line.startswith("scheduler: NOT CHECKED: ")]
    assert len(said) == 1 and "SyntaxError" in said[0], out
    assert any(line.startswith("vision: ") and "0 problem(s)" in line for line in out), out
    assert out[-1].startswith("check: PROBLEMS FOUND (1 node(s) not checked)"), out
    for args in (["check", str(path), "--node", "scheduler"], ["replay", str(path), "--node", "scheduler"]):
        status, err = run(args, tmp_path, capsys)
        assert status == 2 and len(err) == 1, err
        assert "scheduler" in err[0] and "SyntaxError" in err[0]
    # ESPRIT: a composite IOTA's stored text
    from iotad.esprit import load_text
    esprit = tmp_path / "clocked.mcap"
    record_run(load_text(COMPOSITE, "clocked.iota").factory("clocked")("clocked"), esprit, until=5,
               inputs=[{"t": 0.0, "action": "go"}])
    path = rewrite(esprit, tmp_path / "esprit.mcap", attachment=_break_spec("clocked", lambda text: "$" + text))
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "clocked: NOT CHECKED: the spec of node 'clocked' stored in" in out and "does not build: EspritError" in out


@pytest.mark.parametrize("damage", [lambda data: None, lambda data: b"{not json", lambda data: b"[1, 2]"],
                         ids=["dropped", "not-json", "a-list"])
def test_check_does_not_pass_a_node_it_could_not_check(recorded, tmp_path, capsys, damage):
    path = rewrite(recorded, tmp_path / "nospec.mcap",
                   attachment=lambda name, data: damage(data) if name == "spec/scheduler.json" else data)
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "scheduler: NOT CHECKED: the recording holds no readable spec of it" in out
    assert "vision: conforms" in out or "vision:" in out  # the others are still checked
    assert "check: PROBLEMS FOUND (1 node(s) not checked)" in out


def test_check_does_not_pass_a_recording_cut_short(recorded, tmp_path, capsys):
    data = recorded.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) * 2 // 3])
    assert not read_recording(cut).complete
    assert main(["check", str(cut)]) == 1
    out = capsys.readouterr().out
    assert "INCOMPLETE recording" in out and f"iotad recover {cut}" in out
    assert "check: PROBLEMS FOUND (the recording is incomplete)" in out
    assert main(["check", str(recorded)]) == 0  # the whole one passes
    assert "every node conforms" in capsys.readouterr().out


def test_an_infinite_value_in_a_trace_line_is_written_and_read_back():
    event = {"t": 1.0, "iota": "s", "action": "req", "index": 0, "kind": "input",
             "value": {"epoch": math.inf, "timeout": 1.0}}
    line = dumps(event)
    assert '"epoch": Infinity' in line
    assert next(read([line]))["value"]["epoch"] == math.inf
    assert "Infinity" not in dumps(dict(event, value={"epoch": 2.0}))  # plain JSON when it can be


def flipped(source, target, where):
    """A copy of `source` with one bit flipped at the offset `where(bytes)` gives."""
    data = bytearray(source.read_bytes())
    data[where(bytes(data))] ^= 0x01
    target.write_bytes(data)
    return target


ZSTD_FRAME = b"\x28\xb5\x2f\xfd"
BIT_FLIPS = {
    "in a chunk": lambda data: data.index(ZSTD_FRAME) + 100,
    "in a spec attachment": lambda data: data.index(b"spec/scheduler.json") + 300,
    "at the middle of the file": lambda data: len(data) // 2,
}


@pytest.mark.parametrize("reader", READERS, ids=lambda r: r[0])
@pytest.mark.parametrize("where", BIT_FLIPS, ids=lambda w: w.replace(" ", "-"))
def test_one_flipped_bit_is_a_damaged_recording_not_a_pass(recorded, tmp_path, capsys, reader, where):
    """Chunks and attachments carry CRCs: a bit that changed after the file was written makes
    every reader refuse the recording in one line (before, check passed and replay 'agreed' on
    whatever was left)."""
    damaged = flipped(recorded, tmp_path / "flipped.mcap", BIT_FLIPS[where])
    status, err = run([*reader[:1], str(damaged), *reader[1:]], tmp_path, capsys)
    assert status == 2, err
    assert len(err) == 1 and f"{damaged}: damaged: " in err[0] and "fails its CRC" in err[0], err
    assert f"'iotad recover {damaged}' keeps what comes before the damage" in err[0]
    assert not (tmp_path / "out.mcap").exists()


def test_recover_keeps_what_comes_before_the_damage(recorded, tmp_path, capsys):
    whole = read_recording(recorded)
    damaged = flipped(recorded, tmp_path / "flipped.mcap", BIT_FLIPS["in a chunk"])
    out = tmp_path / "kept.mcap"
    assert main(["recover", str(damaged), "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "is damaged (a chunk fails its CRC" in said and "what comes before the damage is kept" in said
    kept = read_recording(out)
    assert kept.complete and len(kept.messages) < len(whole.messages)
    assert [m.data for m in kept.messages] == [m.data for m in whole.messages[:len(kept.messages)]]
    assert {a.name for a in kept.attachments} == {a.name for a in whole.attachments}  # they come first
    assert kept.metadata["iotad.recovered"]["damaged"].startswith("a chunk fails its CRC")


def test_export_and_recover_keep_a_recording_already_at_their_output(recorded, tmp_path, capsys):
    out = tmp_path / "there.mcap"
    out.write_bytes(recorded.read_bytes())
    for args in (["export", str(recorded), "-o", str(out), "--json"], ["recover", str(recorded), "-o", str(out)]):
        assert main(args) == 2
        assert "a recording is already there" in capsys.readouterr().err
        assert out.read_bytes() == recorded.read_bytes()
        assert main([*args, "--force"]) == 0
        capsys.readouterr()
        out.write_bytes(recorded.read_bytes())


def test_a_recovered_copy_of_a_cut_recording_says_so_and_is_no_pass(recorded, tmp_path, capsys):
    """`iotad recover` makes a whole file of what a cut recording holds; the run's end is still
    missing, so info says RECOVERED and check's verdict is PROBLEMS, naming why."""
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    from iotad.recording.engine_sink import EngineRecorder

    chunked = tmp_path / "chunked.mcap"  # a chunk a second, as a recorder flushes: a cut keeps some
    sink = McapSink(chunked)
    root = figure2()
    engine = Engine(root, VirtualClock(), sinks=[EngineRecorder(sink, root)])
    for t in range(1, 31):
        engine.run(t)
        sink.flush()
    sink.finish()
    data = chunked.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:len(data) * 17 // 20])  # the specs are the file's first half: past them
    recovered = tmp_path / "recovered.mcap"
    assert main(["recover", str(cut), "-o", str(recovered)]) == 0
    assert read_recording(recovered).messages
    capsys.readouterr()
    assert main(["info", str(recovered)]) == 0
    assert f"RECOVERED by 'iotad recover' from {cut} (cut short" in capsys.readouterr().out
    assert main(["check", str(recovered)]) == 1
    assert "PROBLEMS FOUND (it was recovered from a cut recording)" in capsys.readouterr().out
    whole = tmp_path / "whole.mcap"
    assert main(["recover", str(recorded), "-o", str(whole)]) == 0  # already whole: a plain copy
    capsys.readouterr()
    assert main(["check", str(whole)]) == 0


def test_long_reads_and_checks_say_what_they_are_doing(recorded, tmp_path, capsys, monkeypatch):
    """Reading a long recording reports how far it is every PROGRESS_EVERY s; check names each
    node as it goes when the recording is long (here: the thresholds made small)."""
    from iotad.recording import verdict
    from iotad.recording import mcap_reader

    monkeypatch.setattr(mcap_reader, "PROGRESS_EVERY", 0.0)
    monkeypatch.setattr(verdict, "LONG", 10)
    capsys.readouterr()
    assert main(["check", str(recorded)]) == 0
    err = capsys.readouterr().err
    assert f"reading {recorded}:" in err and "% (" in err and " MB)" in err
    assert "checking scheduler (" in err and "checking the delivery of " in err


def test_a_json_copy_of_a_cut_recording_says_it_is_part_of_a_run(recorded, tmp_path, capsys):
    """`iotad export --json` of a cut recording writes a whole file: it says so on the terminal
    and in its metadata (for Foxglove's viewers), and iotad's tools refuse it as a JSON copy even
    when it holds no message at all (the JSON channels were how they told)."""
    from mcap.reader import make_reader

    data = recorded.read_bytes()
    for keep, messages in ((len(data) * 17 // 20, True), (200, False)):  # some messages; none, only the header
        cut = tmp_path / f"cut-{keep}.mcap"
        cut.write_bytes(data[:keep])
        out = tmp_path / f"json-{keep}.mcap"
        assert main(["export", str(cut), "-o", str(out), "--json"]) == 0
        said = capsys.readouterr().out
        assert f"{cut} is cut short" in said and "its metadata says so (iotad.recovered)" in said
        with open(out, "rb") as stream:
            metadata = {m.name: dict(m.metadata) for m in make_reader(stream).iter_metadata()}
        assert metadata["iotad.recovered"]["from"] == str(cut)
        assert metadata["iotad.recovered"]["was_complete"] == "false"
        assert metadata["iotad.exported"] == {"from": str(cut), "encoding": "json"}
        assert main(["info", str(out)]) == 2
        assert "a JSON copy for Foxglove" in capsys.readouterr().err
    whole = tmp_path / "whole.json.mcap"
    assert main(["export", str(recorded), "-o", str(whole), "--json"]) == 0
    assert "cut short" not in capsys.readouterr().out
