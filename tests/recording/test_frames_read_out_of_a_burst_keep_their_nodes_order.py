"""A station's burst read back frame by frame keeps its node's order. In real time a node's trace
burst carries many events, and the recorder logs them all at the burst's one receipt time: the
frames read out of a `can_rx_burst` (or `can_tx_burst`) event among them must come right after
that event, not ahead of events the engine took before it. Found in a real-time run of the arm
whose motor node was killed: the drives took the restarted node's Clear_Errors alone, then its
arming frames together, both in one trace burst, and the frames read back put Clear_Errors last
(tests/can_hil/test_motor_node_killed_mid_motion_over_can_in_real_time.py failed once)."""
from iotad.recording.bursts import expand
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import RecordedMessage, Recording

TRACE = "iota/arm/odrives/@trace"
RECEIVED = 1_000_000_000  # the receipt time of the one trace burst that carried both events


def frame(command: int) -> dict:
    return {"id": 1 << 5 | command, "data": [0] * 8, "extended": False, "rtr": False}


def recording(events: list[dict]) -> Recording:
    messages = [RecordedMessage(TRACE, RECEIVED, RECEIVED, k, packb(event)) for k, event in enumerate(events)]
    return Recording("rt.mcap", messages=messages, metadata={"iotad.run": {}}, built=True)


def test_frames_received_together_come_after_the_frame_received_before_them():
    clear, mode, limits = frame(0x18), frame(0x0B), frame(0x0F)
    events = [
        {"t": 12.7319, "iota": "odrives", "action": "can_rx", "index": None, "kind": "input", "value": clear},
        {"t": 12.7320, "iota": "odrives", "action": "can_rx_burst", "index": None, "kind": "input",
         "value": [mode, limits]},
    ]
    read = recording(events)
    expand(read, RecordedMessage)
    taken = [(e["action"], e["value"]["id"] & 0x1F if e["action"] == "can_rx" else None)
             for e in read.trace("odrives")]
    assert taken == [("can_rx", 0x18), ("can_rx_burst", None), ("can_rx", 0x0B), ("can_rx", 0x0F)]
    # without the derived frames, the node's own events as it took them
    assert [e["action"] for e in read.trace("odrives", derived=False)] == ["can_rx", "can_rx_burst"]


def test_a_sent_burst_reads_back_after_what_its_node_did_before_it():
    events = [
        {"t": 2.0, "iota": "motor", "action": "setpoints", "index": None, "kind": "input", "value": [0.1]},
        {"t": 2.0, "iota": "motor", "action": "can_tx_burst", "index": None, "kind": "output",
         "value": [frame(0x0C), frame(0x07)]},
        {"t": 2.0, "iota": "motor", "action": "tick", "index": None, "kind": "internal"},
    ]
    read = recording([dict(e) for e in events])
    for message in read.messages:
        message.topic = "iota/arm/motor/@trace"
    expand(read, RecordedMessage)
    order = [(e["action"], e.get("derived", False)) for e in read.trace("motor")]
    assert order == [("setpoints", False), ("can_tx_burst", False), ("can_tx", True), ("can_tx", True),
                     ("tick", False)]
