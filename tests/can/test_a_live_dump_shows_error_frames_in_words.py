"""`iotad candump --live` (and `python -m iotad.can.dump`) show what a live bus carries: its frames
decoded, and also what no IOTA can take, which used to vanish: an error frame in words, whatever
the filters (it concerns the whole bus), and a CAN FD frame."""
import uuid

import can

from iotad.can import odrive
from iotad.can.bus import open_bus
from iotad.can.dump import live_lines


def test_error_and_fd_frames_are_lines_beside_the_filtered_frames():
    channel = f"live-dump-{uuid.uuid4().hex}"
    bus = open_bus("virtual", channel)
    other = can.Bus(interface="virtual", channel=channel)
    try:
        other.send(odrive.encode(3, "Estop").to_can_message())                   # filtered out below
        other.send(can.Message(arbitration_id=0x040 | 0x004, is_error_frame=True, data=bytes([0, 0x10, 0, 0, 0, 0, 0, 0])))
        other.send(can.Message(arbitration_id=0x123, is_fd=True, data=bytes(16), is_extended_id=False))
        other.send(odrive.encode(5, "Estop").to_can_message())
        axis5 = lambda frame: frame.id >> 5 == 5  # noqa: E731
        lines = list(live_lines(bus, timeout=5.0, count=3, keep=axis5))
    finally:
        other.shutdown()
        bus.shutdown()
    assert [line.split()[1:3] for line in lines] == [["rx", "ERROR"], ["rx", "not"], ["rx", "0A2"]]
    assert lines[0].endswith("ERROR  controller problem (RX error passive); bus off")
    assert lines[1].endswith("not a classic frame: CAN FD frame 0x123 with 16 bytes is not classic CAN")
    assert lines[2].endswith("Estop node=5")


def test_a_quiet_bus_ends_the_dump_after_its_timeout():
    bus = open_bus("virtual", f"quiet-{uuid.uuid4().hex}")
    try:
        assert list(live_lines(bus, timeout=0.05)) == []
    finally:
        bus.shutdown()
