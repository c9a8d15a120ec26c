"""Systems and recording helpers several test folders share: the Figure 2 demo system, an ESPRIT
composite, a way to tamper with a recorded trace, a message-by-message copy of a recording with
payloads or attachments changed (`rewrite`), and the check of a real-time run's recording."""
import contextlib
import io
import re

from iotad.cli import main
from iotad.kernel.compose import Composite
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording, RecordedMessage
from iotad.recording.mcap_sink import McapSink
from requesters import Requester
from scheduler import Scheduler


def figure2(vision_pause=0.5):
    """The `iotad demo` system: a scheduler (N=2, T=0.5) and two requesters."""
    return Composite(
        "figure2",
        Scheduler("scheduler", N=2, T=0.5),
        Requester("vision", priority=1, epoch=3.0, timeout=4.0, start=0.0, pause=vision_pause, setpoint=0.2),
        Requester("manipulation", priority=5, epoch=2.0, timeout=3.0, start=1.0, pause=4.0, setpoint=1.5),
        bind=[("vision.req", "scheduler.req[0]"), ("manipulation.req", "scheduler.req[1]"),
              ("scheduler.ack[0]", "vision.ack"), ("scheduler.ack[1]", "manipulation.ack")])


COMPOSITE = """
iota counter: tick()/0 -> count(int)/0 {
  states int n = 0; bool dirty = false;
  actions
  tick() do { n = n + 1; dirty = true; }
  count(n) when dirty do dirty = false;
}
iota doubler: inp(int)/0 -> out(int)/0 {
  states int v = 0; bool full = false;
  actions
  inp(x) do { v = x * 2; full = true; }
  out(v) when full after 0.5 do full = false;
}
iota clocked(float P = 1.0, int TIMES = 3): go()/0 -> tick()/0, total(int)/0 {
  states int sent = 0; bool running = false;
  include
    counter c;
    doubler d;
    tick -> c.tick;          // an output of clocked's own feeds a component
    c.count -> d.inp;
    d.out -> total;          // a component's output is clocked's output
  actions
  go() do running = true;
  tick() when running && sent < TIMES after P do sent = sent + 1;
}
"""


def mutate(source, target, node, change, extra=()):
    """Copy a recording with `change(events) -> events` applied to `node`'s @trace (re-sorted by t),
    and the messages `extra` ((topic, t, value) each) added."""
    recording = read_recording(source)
    topic = f"iota/{recording.system}/{node}/@trace"
    # (a format 2 burst's per-frame events are the reader's, not the file's: the copy holds the burst)
    events = [m.value for m in recording.messages if m.topic == topic and not m.derived]
    events = sorted(change(events), key=lambda e: e["t"])
    others = [m for m in recording.messages if m.topic != topic and not m.derived]
    others += [RecordedMessage(where, int(t * 1e9), int(t * 1e9), k, packb(value))
               for k, (where, t, value) in enumerate(extra)]
    mutated = [RecordedMessage(topic, int(e["t"] * 1e9), int(e["t"] * 1e9), k, packb(e)) for k, e in enumerate(events)]
    sink = McapSink(target)
    for attachment in recording.attachments:
        sink.attach(attachment.name, attachment.media_type, attachment.data)
    for name, data in recording.metadata.items():
        sink.writer.add_metadata(name, data)
    for message in sorted(others + mutated, key=lambda m: m.log_time):
        channel = sink.channel(message.topic, "any", {})
        sink.write(channel, message.log_time, message.publish_time, message.sequence, message.data)
    sink.finish()
    return target


def find(events, **fields):
    return next(k for k, e in enumerate(events) if all(e.get(f) == v for f, v in fields.items()))


def check_of_a_real_run(path, *options: str) -> str:
    """`iotad check --all` of a recording of real processes, asserted to find nothing but lateness;
    returns its report. Processes on a loaded machine (two cores, the test suite beside them) can
    fire some ms past a window: check rightly finds it, `late`, but that is the machine's load,
    not the system, and the tests that run real processes are about what the system did. Any
    other finding (a wrong value, an action not enabled, a message not delivered as sent, a node
    not checked) fails, as does a pass that is not whole; so does an expired window, unless the
    same action of the same enabling fired late after it (an event of another node came between
    its window's end and its late firing: the one lateness, found twice). `options`: more of
    `iotad check`'s options (`--no-delivery` for a run whose delivery the test judges itself)."""
    report = io.StringIO()
    with contextlib.redirect_stdout(report):
        code = main(["check", str(path), "--all", *options])
    out = report.getvalue()
    verdict = out.strip().splitlines()[-1]
    if code == 0:
        assert verdict.startswith("check: every node conforms to its spec"), out
    else:
        assert verdict.startswith("check: PROBLEMS FOUND (conformance) "), out
        findings = re.findall(r"^  t=\S+ \[(\w+)\] (.*)$", out, re.M)
        assert {kind for kind, _ in findings} <= {"late", "expired"} and findings, out
        fired_late = set(re.findall(r"\((\S+) enabled at t=(\S+)\)$", "\n".join(
            text for kind, text in findings if kind == "late"), re.M))
        for kind, text in findings:
            if kind == "expired":
                expired = re.match(r"(\S+) was enabled at t=(\S+) and had to fire by", text)
                assert expired and expired.groups() in fired_late, out
    return out


def rewrite(source, target, data=lambda topic, k, data: data, attachment=lambda name, data: data):
    """Copy a recording message by message: `data(topic, k, bytes)` is the k-th message of that
    topic's new payload; `attachment(name, bytes)` an attachment's (None drops it)."""
    recording = read_recording(source)
    sink = McapSink(target)
    for item in recording.attachments:
        changed = attachment(item.name, item.data)
        if changed is not None:
            sink.attach(item.name, item.media_type, changed)
    for name, fields in recording.metadata.items():
        sink.writer.add_metadata(name, fields)
    seen = {}
    for message in recording.messages:
        k = seen[message.topic] = seen.get(message.topic, -1) + 1
        channel = sink.channel(message.topic, "any", {})
        sink.write(channel, message.log_time, message.publish_time, message.sequence,
                   data(message.topic, k, message.data))
    sink.finish()
    return target
