"""A node's CAN port hands its IOTA classic frames only; what else the bus brings is recorded, not
dropped unseen: error frames (a controller's report of bus off, no ACK, error passive...) in
words, CAN FD frames, and a bus that fails on receive, which is retried every RETRY seconds
instead of spun on. One record per kind and period, with its count (`take_problems`)."""
import threading
import uuid

import can

from iotad.can.bus import RealTimeBus
from iotad.can.error_frames import describe_error_frame
from iotad.node_host.can_port import ERROR_FRAME, RECEIVE_FAILED, RETRY, UNUSABLE, CanPort


def test_error_frames_are_described_from_their_class_bits_and_data():
    assert describe_error_frame(0x040, b"") == "bus off"
    assert describe_error_frame(0x004 | 0x200, bytes([0, 0x20 | 0x04, 0, 0, 0, 0, 136, 3])) == \
        "controller problem (RX warning level, TX error passive); error counters TX 136, RX 3"
    assert describe_error_frame(0x008 | 0x020, bytes([0, 0, 0x04 | 0x80])) == \
        "protocol violation (bit stuffing error, error while transmitting); no ACK on transmission"
    assert describe_error_frame(0x002, bytes([17])) == "lost arbitration (in bit 17)"
    assert describe_error_frame(0x400, b"") == "unspecified error (class bits 0x400)"


class Inbox:
    """The engine side of the port: the frames posted, and an event when the last expected came."""

    def __init__(self, expected: int):
        self.items, self.expected, self.done = [], expected, threading.Event()

    def post(self, item):
        self.items.append(item)
        if len(self.items) >= self.expected:
            self.done.set()


def test_error_and_fd_frames_are_recorded_and_data_frames_still_delivered():
    channel = f"error-frames-{uuid.uuid4().hex}"
    inbox = Inbox(expected=1)
    port = CanPort({"bus": "arm_bus", "interface": "virtual", "channel": channel}, inbox.post, now=lambda: 2.5)
    port.open()
    other = can.Bus(interface="virtual", channel=channel)
    try:
        for _ in range(3):
            other.send(can.Message(arbitration_id=0x040 | 0x004, is_error_frame=True,
                                   data=bytes([0, 0x20, 0, 0, 0, 0, 0, 0])))
        other.send(can.Message(arbitration_id=0x123, is_fd=True, data=bytes(12), is_extended_id=False))
        other.send(can.Message(arbitration_id=0x009, data=bytes([1, 2, 3, 4]), is_extended_id=False))
        assert inbox.done.wait(5.0), "the data frame never reached the engine's side"
    finally:
        other.shutdown()
        port.close()
    [frame] = inbox.items
    assert (frame.name, frame.key) == ("can_rx", "can/arm_bus")  # only the classic data frame
    problems = {violation: (message, count) for violation, message, count in port.take_problems()}
    assert set(problems) == {ERROR_FRAME, UNUSABLE}
    message, count = problems[ERROR_FRAME]
    assert count == 3
    assert message == ("CAN bus 'arm_bus': 3 error frame(s) between t=2.500000 and t=2.500000; "
                       "the first: controller problem (TX error passive); bus off")
    message, count = problems[UNUSABLE]
    assert count == 1 and "CAN FD frame 0x123 with 12 bytes is not classic CAN" in message
    assert port.take_problems() == []  # handed over once


class FailingBus:
    """A bus whose receive raises `failures` times (an interface gone down), then is quiet."""

    def __init__(self, failures: int):
        self.failures, self.calls, self.quiet = failures, 0, threading.Event()

    def recv(self, timeout=None):
        self.calls += 1
        if self.calls <= self.failures:
            raise can.CanOperationError("Error receiving: Network is down")
        self.quiet.set()
        return None

    def shutdown(self):
        pass


class RecordedWaits(threading.Event):
    """The port's stop event, noting every pause the reader takes."""

    def __init__(self):
        super().__init__()
        self.waits = []

    def wait(self, timeout=None):
        self.waits.append(timeout)
        return self.is_set()


def test_a_failing_bus_is_retried_after_a_pause_and_recorded():
    port = CanPort({"bus": "arm_bus", "interface": "virtual", "channel": "unused"}, lambda item: None,
                   now=lambda: 7.0)
    bus = FailingBus(failures=3)
    port.bus = RealTimeBus(bus, "virtual", "unused")
    port._stop = stop = RecordedWaits()
    port._thread = threading.Thread(target=port._receive, daemon=True)
    port._thread.start()
    try:
        assert bus.quiet.wait(5.0)
    finally:
        stop.set()
        port._thread.join(5.0)
    assert stop.waits == [RETRY] * 3  # one pause after each failure: no busy loop
    [(violation, message, count)] = port.take_problems()
    assert (violation, count) == (RECEIVE_FAILED, 3)
    assert message == ("CAN bus 'arm_bus': 3 failed receive(s), retried every 0.1 s between t=7.000000 and "
                       "t=7.000000; the first: CanOperationError: Error receiving: Network is down")



def test_a_node_host_records_an_error_frame_on_its_trace():
    """End to end in one process (python-can's `virtual` bus is in-process): a bus logger's node
    host hears an error frame; its trace carries the violation at the next heartbeat."""
    from iotad.can.frame_log import BusLogger
    from iotad.node_host.node_config import from_dict
    from iotad.node_host.node_host import NodeHost
    from node_harness import Hub, node_config

    hub = Hub()
    channel = f"node-host-{uuid.uuid4().hex}"
    config = node_config(hub, "arm_bus", "iotad.can.frame_log:BusLogger",
                         can={"bus": "arm_bus", "interface": "virtual", "channel": channel, "listen_only": True})
    host = NodeHost(from_dict(config), BusLogger("arm_bus"))
    other = None
    try:
        hub.subscribe("iota/test/arm_bus/@trace")
        host.start()
        other = can.Bus(interface="virtual", channel=channel)
        other.send(can.Message(arbitration_id=0x020, is_error_frame=True, data=bytes(8)))
        event = hub.wait_value("iota/test/arm_bus/@trace",
                               lambda e: e.get("kind") == "violation", what="the error frame's violation")
    finally:
        if other is not None:
            other.shutdown()
        host.close()
        hub.close()
    assert (event["action"], event["value"]["violation"], event["value"]["count"]) == ("can_rx", ERROR_FRAME, 1)
    assert event["value"]["message"].endswith("the first: no ACK on transmission")
