"""A CAN receiver that froze (SIGSTOP, a stalled machine) drains its socket's backlog when it
thaws: every frame arrives, in order, late. So does one whose socket opened long before its
engine started (a slow start on a loaded machine): the frames sent between the two arrive at the
start, together. The delivery check counts those frames delivered,
with their latency, and reports no loss, no alteration and no reordering. With frames that are
all alike (an ODrive's heartbeat is), it used to take an older twin that waited past its window
for lost, pair the backlog with the newest twins, and call the frames left over 'altered'."""
from iotad.node_host import wire
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink

SYSTEM = """[system]
name = "pp"
[[node]]
name = "pinger"
python = "pinger.py:Pinger"
[[node]]
name = "echo"
python = "echo.py:Echo"
[[can]]
name = "can0"
interface = "socketcan"
channel = "vcan0"
stations = ["pinger", "echo"]
log = false
"""
FRAME = {"id": 0x10, "extended": False, "rtr": False, "dlc": 1, "data": [0] * 8}  # the same every time
PERIOD = 0.01


def event(node: str, t: float, kind: str, action: str, value=None) -> dict:
    return {"t": t, "iota": node, "action": action, "index": None, "kind": kind, "value": value}


def recording_with_a_frozen_receiver(path, frozen=(0.30, 0.60)):
    """The pinger sends FRAME every 10 ms from t=0.1 to 1.0; the echo receives each 0.5 ms later,
    except while it is frozen: the frames sent then arrive together, in order, as it thaws."""
    events = [("pinger", event("pinger", 0.0, "start", "@start", {"wall": 100.0, "pid": 1})),
              ("echo", event("echo", 0.0, "start", "@start", {"wall": 100.0, "pid": 2}))]
    thaw = frozen[1]
    sent = [round(0.1 + k * PERIOD, 6) for k in range(91)]
    for k, t in enumerate(sent):
        events.append(("pinger", event("pinger", t, "output", "can_tx", FRAME)))
        heard = t + 0.0005 if not frozen[0] <= t < thaw else thaw + 0.0001 * k  # the backlog, in order
        events.append(("echo", event("echo", heard, "input", "can_rx", FRAME)))
    for t in (0.5, 1.0, 2.0):  # the echo's heartbeats say it lived through, and a second longer
        events.append(("echo", event("echo", t, "internal", "tick")))
    return written(path, events), len(sent)


def written(path, events):
    sink = McapSink(path)
    sink.add_metadata("iotad.recording", {"system": '"pp"', "clock": '"real"', "source": '"traces"'})
    sink.attach("system.toml", "application/toml", SYSTEM.encode())
    channels = {node: sink.channel(wire.trace_key("pp", node), "iotad.trace_event", {}) for node in ("pinger", "echo")}
    for seq, (node, e) in enumerate(sorted(events, key=lambda item: item[1]["t"])):
        ns = int(e["t"] * 1e9)
        sink.write(channels[node], ns, ns, seq, wire.encode(e))
    sink.finish()
    return read_recording(path)


def recording_with_a_slow_start(path, opened=0.30, started=0.55):
    """The pinger sends FRAME every 10 ms from t=0.1 to 1.0. The echo's socket opens at `opened`,
    its engine starts at `started`: the frames sent in between arrive together, in order, at the
    start; those before `opened` never reach it; the rest arrive 0.5 ms after they were sent."""
    events = [("pinger", event("pinger", 0.0, "start", "@start", {"wall": 100.0, "pid": 1})),
              ("echo", event("echo", started, "start", "@start", {"wall": 100.0 + started, "pid": 2}))]
    sent = [round(0.1 + k * PERIOD, 6) for k in range(91)]
    for k, t in enumerate(sent):
        events.append(("pinger", event("pinger", t, "output", "can_tx", FRAME)))
        if t >= opened:
            heard = t + 0.0005 if t >= started else started + 0.0001 * k
            events.append(("echo", event("echo", heard, "input", "can_rx", FRAME)))
    for t in (0.8, 1.0, 2.0):
        events.append(("echo", event("echo", t, "internal", "tick")))
    return written(path, events), sum(1 for t in sent if t >= opened), sum(1 for t in sent if t < opened)


def test_the_backlog_of_a_frozen_receiver_is_delivered_late_in_order(tmp_path):
    recording, count = recording_with_a_frozen_receiver(tmp_path / "frozen.mcap")
    report = check_delivery(recording)
    link = next(link for link in report.links if link.label == "can can0: pinger -> echo")
    problems = [f.message for f in report.findings if f.link == link.label and f.problem]
    assert (link.sent, link.delivered, link.lost, link.altered) == (count, count, 0, 0), problems[:3]
    assert problems == []
    assert max(link.latencies) > 0.25  # the first frame of the backlog waited ~0.3 s


def test_a_frame_the_frozen_receiver_never_got_is_still_lost(tmp_path):
    recording, count = recording_with_a_frozen_receiver(tmp_path / "frozen.mcap")
    # drop one reception from the middle of the backlog (its socket overflowed); the frames are
    # all alike, so which one was lost cannot be told: one of them is, and none is altered
    dropped = next(m for m in recording.messages if m.topic == wire.trace_key("pp", "echo")
                   and m.value["kind"] == "input" and 0.6 < m.value["t"] < 0.61)
    recording.messages.remove(dropped)
    link = next(link for link in check_delivery(recording).links if link.label == "can can0: pinger -> echo")
    assert (link.delivered, link.lost, link.altered) == (count - 1, 1, 0)


def test_the_backlog_of_a_socket_opened_long_before_its_engine_started_is_delivered(tmp_path):
    # 0.25 s between the socket and the engine: more than the 0.1 s a frame may wait for the bus
    recording, heard, unheard = recording_with_a_slow_start(tmp_path / "slow.mcap")
    report = check_delivery(recording)
    link = next(link for link in report.links if link.label == "can can0: pinger -> echo")
    problems = [f.message for f in report.findings if f.link == link.label and f.problem]
    assert (link.delivered, link.lost, link.altered, link.unjudged) == (heard, 0, 0, unheard), problems[:3]
    assert problems == []
    assert max(link.latencies) > 0.2  # the first frame of the backlog waited ~0.25 s
