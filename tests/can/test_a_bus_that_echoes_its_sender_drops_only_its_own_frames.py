"""python-can's udp_multicast hands every frame back to the socket that sent it. `RealTimeBus`
with `filter_own` drops exactly one returning copy per send (equal frames are interchangeable),
delivers every frame of another station, also one equal to a frame it sent once its own copy has
come back, and forgets sends that never came back after OWN_WAIT seconds."""
import can

from iotad.can.bus import OWN_LIMIT, OWN_WAIT, RealTimeBus
from iotad.can.frame import Frame


class LoopbackBus:
    """A python-can bus as udp_multicast behaves: what it sends comes back, after what others sent."""

    def __init__(self):
        self.incoming: list[can.Message] = []

    def send(self, msg, timeout=None):
        self.incoming.append(msg)

    def recv(self, timeout=None):
        return self.incoming.pop(0) if self.incoming else None

    def hear(self, frame: Frame):  # a frame another station sent
        self.incoming.append(frame.to_can_message())


def bus_and_clock():
    raw = LoopbackBus()
    bus = RealTimeBus(raw, "udp_multicast", "239.74.163.2", filter_own=True)
    now = [100.0]
    bus.clock = lambda: now[0]
    return raw, bus, now


def received(bus):
    out = []
    while (got := bus.recv_frame(timeout=0)) is not None:
        out.append(got[1])
    return out


def test_own_frames_are_dropped_and_every_other_station_s_frame_is_delivered():
    raw, bus, _ = bus_and_clock()
    a, b, c = Frame(0x10, b"\x01"), Frame(0x10, b"\x02"), Frame(0x21, b"\x01\x02")
    bus.send(a)
    raw.hear(c)
    bus.send(b)
    bus.send(can.Message(arbitration_id=0x10, data=b"\x01", is_extended_id=False))  # a again, as a message
    raw.hear(a)  # another station sends a frame equal to ours, after our two copies of it
    assert received(bus) == [c, a]
    assert bus.sent == 3 and bus.received == 2 and bus._outstanding == 0


def test_remote_frames_and_extended_ids_are_told_apart():
    raw, bus, _ = bus_and_clock()
    bus.send(Frame(0x10, b"", rtr=True))
    raw.hear(Frame(0x10, b""))
    raw.hear(Frame(0x10, b"", extended=True))
    assert received(bus) == [Frame(0x10, b""), Frame(0x10, b"", extended=True)]


def test_a_send_that_never_came_back_is_forgotten_and_cannot_hide_a_later_frame():
    raw, bus, now = bus_and_clock()
    a = Frame(0x10, b"\x05")
    bus.send(a)
    raw.incoming.clear()  # our copy was lost in a socket buffer
    now[0] += OWN_WAIT + 1
    bus.send(Frame(0x7FF, b""))  # a send sweeps what waited too long
    raw.hear(a)
    assert received(bus) == [a]


def test_a_flood_of_sends_that_never_come_back_is_bounded():
    raw, bus, _ = bus_and_clock()
    for k in range(OWN_LIMIT + 10):
        bus.send(Frame(0x10, k.to_bytes(2, "little")))
    raw.incoming.clear()
    assert bus._outstanding <= OWN_LIMIT
