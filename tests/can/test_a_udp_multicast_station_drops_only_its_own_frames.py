"""udp_multicast hands every frame back to the socket that sent it. iotad's station
(`iotad.can.udp_multicast`) drops exactly one returning copy per send, by its bytes (equal frames
are interchangeable), delivers every frame of another station, also one equal to a frame it sent
once its own copy has come back, and forgets sends that never came back after OWN_WAIT seconds.
It shares a bus with python-can's own udp_multicast station, the third party whose wire format it
speaks: each hears the other's frames exactly, and a datagram that is no frame is handed back as
a FrameError, not raised."""
import pytest

from iotad.can.udp_multicast import OWN_LIMIT, OWN_WAIT, OwnEchoes, pack, plain_of, _fields
from iotad.can.frame import Frame, FrameError


def echoes_and_clock():
    now = [100.0]
    return OwnEchoes(clock=lambda: now[0]), now


def test_one_returning_copy_is_dropped_per_send_and_an_equal_frame_after_it_is_delivered():
    own, _ = echoes_and_clock()
    a, b = pack(Frame(0x10, b"\x01")), pack(Frame(0x10, b"\x02"))
    own.sent(a)
    own.sent(b)
    own.sent(a)
    assert [own.came_back(x) for x in (pack(Frame(0x21, b"\x01\x02")), a, b, a, a)] == [False, True, True, True, False]
    assert own.outstanding == 0


def test_remote_frames_and_extended_ids_are_told_apart():
    own, _ = echoes_and_clock()
    own.sent(pack(Frame(0x10, b"", rtr=True)))
    assert not own.came_back(pack(Frame(0x10, b"")))
    assert not own.came_back(pack(Frame(0x10, b"", extended=True)))
    assert own.came_back(pack(Frame(0x10, b"", rtr=True)))


def test_a_send_that_never_came_back_is_forgotten_and_cannot_hide_a_later_frame():
    own, now = echoes_and_clock()
    a = pack(Frame(0x10, b"\x05"))
    own.sent(a)  # our copy is lost in a socket buffer
    now[0] += OWN_WAIT + 1
    own.sent(pack(Frame(0x7FF, b"")))  # a send sweeps what waited too long
    assert not own.came_back(a)


def test_a_flood_of_sends_that_never_come_back_is_bounded():
    own, _ = echoes_and_clock()
    for k in range(OWN_LIMIT + 10):
        own.sent(pack(Frame(0x10, k.to_bytes(2, "little"))))
    assert own.outstanding <= OWN_LIMIT


def test_a_datagram_decodes_to_the_value_a_frame_gives():
    import can
    from can.interfaces.udp_multicast.utils import pack_message

    for frame in (Frame(0x123, b"\x01\x02\x03"), Frame(0x1ABCDEF, b"\xff" * 8, extended=True),
                  Frame.remote(0x7FF, 4), Frame(0, b"")):
        assert plain_of(_fields(pack(frame))) == frame.plain()
        assert plain_of(_fields(pack_message(frame.to_can_message()))) == frame.plain()  # python-can's own packing
    error = plain_of(_fields(pack_message(can.Message(arbitration_id=0x004, is_error_frame=True, dlc=8,
                                                      data=bytes(8), is_extended_id=True))))
    assert isinstance(error, can.Message) and error.is_error_frame


@pytest.mark.parametrize("datagram, said", [
    (b"\xc1garbage", "no python-can frame"),
    (b"\x93\x01\x02\x03", "no python-can frame"),
    (pack(Frame(0x10, b"\x01")).replace(b"arbitration_id", b"arbitration_ix"), "does not check"),
])
def test_a_datagram_that_is_no_frame_is_a_frame_error(datagram, said):
    with pytest.raises(FrameError, match=said):
        plain_of(_fields(datagram))


def test_a_standard_id_over_11_bits_is_no_frame():
    import msgpack
    fields = msgpack.unpackb(pack(Frame(0x10, b"\x01")), raw=False)
    fields["arbitration_id"] = 0x800
    with pytest.raises(FrameError, match=r"less than 2\^11"):
        plain_of(fields)


SHARED_BUS = r'''
import json, os, socket, subprocess, sys, time
import can
from iotad.can.bus import open_env_bus
from iotad.can.frame import Frame

group = os.environ["IOTAD_CAN_CHANNEL"]
theirs = can.Bus(interface="udp_multicast", channel=group, port=43113, hop_limit=1, fd=False)  # python-can's
ours = open_env_bus()

def drain(take, seconds=1.0):
    got, deadline = [], time.monotonic() + seconds
    while time.monotonic() < deadline:
        item = take(0.05)
        if item:
            got.append(item)
    return got

sent_by_us = [Frame(0x10 + k, bytes([k] * (k % 9))) for k in range(20)] + [Frame.remote(0x7FF, 3)]
for frame in sent_by_us:
    ours.send_frame(frame)
heard_by_them = [Frame.from_can_message(m) for m in drain(lambda t: theirs.recv(t))]
heard_back = drain(lambda t: ours.recv_plain(t, 64)[0])

sent_by_them = [Frame(0x1ABCDE0 + k, bytes([255 - k] * 8), extended=True) for k in range(20)]
sent_by_them.append(sent_by_us[0])  # a frame equal to one of ours, from another station
for frame in sent_by_them:
    theirs.send(frame.to_can_message())
plains, others = [], []
for got in drain(lambda t: ours.recv_plain(t, 64)):
    plains += got[0]
    others += got[1]
# a datagram that is no frame, then a frame: the first is handed back, the second still comes
raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
raw.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
raw.sendto(b"\xc1 not msgpack", (group, 43113))
theirs.send(Frame(0x42, b"\x42").to_can_message())
after = drain(lambda t: ours.recv_plain(t, 64))
ours.shutdown(); theirs.shutdown()
print("RESULT " + json.dumps({
    "heard_by_them": [f.plain() for f in heard_by_them], "heard_back": heard_back,
    "plains": plains, "others": [str(o) for o in others],
    "after_plains": [p for got in after for p in got[0]], "after_others": [str(o) for got in after for o in got[1]],
}))
'''


def test_iotad_s_station_and_python_can_s_share_a_bus(can_bus):
    import json

    if can_bus.interface != "udp_multicast":
        pytest.skip(f"the tier is {can_bus.name}, which has no udp_multicast station")
    result = can_bus.run_python(SHARED_BUS, timeout=60)
    result.check()
    line = next(line for line in result.output.splitlines() if line.startswith("RESULT "))
    got = json.loads(line[len("RESULT "):])
    ours = [Frame(0x10 + k, bytes([k] * (k % 9))) for k in range(20)] + [Frame.remote(0x7FF, 3)]
    theirs = [Frame(0x1ABCDE0 + k, bytes([255 - k] * 8), extended=True) for k in range(20)] + [ours[0]]
    assert got["heard_by_them"] == [f.plain() for f in ours]   # python-can decodes every frame we sent
    assert got["heard_back"] == []                              # and none of ours comes back to us
    assert got["plains"] == [f.plain() for f in theirs] and got["others"] == []
    assert got["after_plains"] == [Frame(0x42, b"\x42").plain()]
    assert len(got["after_others"]) == 1 and "no python-can frame" in got["after_others"][0]
