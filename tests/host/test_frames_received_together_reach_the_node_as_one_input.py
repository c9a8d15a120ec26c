"""In real time a node's CAN port hands the frames the bus already holds to a node that has a
`can_rx_burst` input (the motor node, the simulated drives, a bus's logger) as one input, in their
order (at most BURST_MAX), instead of one engine step per frame: a node that fell behind catches
up in one step. The node takes them exactly as the same frames on `can_rx` at that instant, and a
reader reads the input back as a `can_rx` per frame from the same key. A node without the input
gets every frame on `can_rx`, as before."""
import struct
import threading

import can

from iotad.can.bus import RealTimeBus
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.node_host.can_port import BURST_MAX, CHECKED_FRAME, CHECKED_FRAMES, ERROR_FRAME, CanPort
from iotad.recording.bursts import is_station_burst, sent_events
from nodes.can_motor import CanMotor


class HeldBus:
    """A bus whose socket already holds `messages`: recv hands them out in order, then nothing."""

    def __init__(self, messages):
        self.messages = list(messages)

    def recv(self, timeout=None):
        return self.messages.pop(0) if self.messages else None

    def shutdown(self):
        pass


def received(messages, burst: bool, expected_items: int):
    items, done = [], threading.Event()

    def post(item):
        items.append(item)
        if sum(len(i.payload) if i.name == "can_rx_burst" else 1 for i in items) >= expected_items:
            done.set()
    port = CanPort({"bus": "arm_bus", "interface": "virtual", "channel": "held"}, post, now=lambda: 1.0, burst=burst)
    port.bus = RealTimeBus(HeldBus(messages), "virtual", "held")
    thread = threading.Thread(target=port._receive, daemon=True)
    thread.start()
    try:
        assert done.wait(5.0), items
    finally:
        port._stop.set()
        thread.join(2.0)
    return items, port


def frame(k: int) -> can.Message:
    return can.Message(arbitration_id=0x029 + (k % 6) * 0x20, data=struct.pack("<ff", k, 0.0), is_extended_id=False)


def test_what_the_bus_holds_goes_in_one_input_in_order():
    error = can.Message(arbitration_id=0x040, is_error_frame=True, data=bytes(8))
    items, port = received([frame(0), frame(1), error, frame(2)], burst=True, expected_items=3)
    [item] = items
    assert (item.name, item.key) == ("can_rx_burst", "can/arm_bus")
    assert item.checked is CHECKED_FRAMES  # built with Frame's checks: the engine does not check them again
    assert [f["data"][:4] for f in item.payload] == [list(struct.pack("<f", k)) for k in range(3)]
    assert [problem for problem, _, _ in port.take_problems()] == [ERROR_FRAME]  # recorded, not passed on


def test_a_flood_goes_in_inputs_of_at_most_burst_max_and_a_lone_frame_on_can_rx():
    items, _ = received([frame(k) for k in range(BURST_MAX + 6)], burst=True, expected_items=BURST_MAX + 6)
    assert [(i.name, len(i.payload)) for i in items] == [("can_rx_burst", BURST_MAX), ("can_rx_burst", 6)]
    items, _ = received([frame(0)], burst=True, expected_items=1)
    assert [(i.name, i.checked) for i in items] == [("can_rx", CHECKED_FRAME)]


def test_a_node_without_the_input_gets_each_frame_on_can_rx():
    items, _ = received([frame(k) for k in range(5)], burst=False, expected_items=5)
    assert [i.name for i in items] == ["can_rx"] * 5


def test_the_motor_node_takes_them_as_the_same_frames_one_by_one():
    joints = [{"name": f"joint{k}", "node_id": k} for k in range(1, 4)]
    heartbeat = struct.pack("<IBBBx", 0, 8, 0, 0)

    def plain(node, cmd, data):
        return {"id": node << 5 | cmd, "extended": False, "rtr": False, "dlc": len(data),
                "data": list(data) + [0] * (8 - len(data))}
    frames = [plain(j, 0x01, heartbeat) for j in (1, 2, 3)] + [plain(j, 0x09, struct.pack("<ff", j, 0.5)) for j in (1, 2, 3)]
    frames.append(plain(9, 0x01, heartbeat))  # a stranger's: a bad_frame either way

    def outputs(post):
        engine = Engine(CanMotor("motor", joints=joints), VirtualClock())
        post(engine)
        engine.run(0.2)
        return [(e["t"], e["action"], e["index"], e["value"]) for e in engine.trace if e["kind"] == "output"]
    one_by_one = outputs(lambda engine: [engine.post(None, "can_rx", f, t=0.05) for f in frames])
    together = outputs(lambda engine: engine.post(None, "can_rx_burst", frames, t=0.05))
    assert together == one_by_one
    assert any(action == "bad_frame" for _, action, _, _ in together)
    assert [value["event"] for _, action, _, value in together if action == "joint_status"][:6].count("ARM_DONE") == 3


def test_a_reader_reads_the_input_back_as_a_can_rx_per_frame_from_its_key():
    event = {"t": 1.5, "iota": "motor", "action": "can_rx_burst", "index": None, "kind": "input",
             "value": [{"id": 0x29, "extended": False, "rtr": False, "dlc": 0, "data": [0] * 8},
                       {"id": 0x49, "extended": False, "rtr": False, "dlc": 0, "data": [0] * 8}],
             "key": "can/arm_bus"}
    assert is_station_burst(event)
    assert [(e["t"], e["action"], e["kind"], e["value"]["id"], e["key"]) for e in sent_events(event)] == [
        (1.5, "can_rx", "input", 0x29, "can/arm_bus"), (1.5, "can_rx", "input", 0x49, "can/arm_bus")]
