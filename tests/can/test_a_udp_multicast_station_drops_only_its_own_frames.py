"""udp_multicast hands every frame back to the socket that sent it. iotad's station
(`iotad.can.udp_multicast`) names itself first in every frame it sends, and a socket filter drops
what begins so before it wakes the receiver (or, with no filter, the receive loop does): it never
hears its own frames, and hears every frame of another station, also one equal to its own. It
shares a bus with python-can's own udp_multicast station, the third party whose wire format it
speaks: each hears the other's frames exactly, and a datagram that is no frame is handed back as a
FrameError, not raised. All of it holds on an IPv6 group too (python-can's default channel is one)."""
import pytest

from iotad.can.udp_multicast import _fields, own_frame_filter, pack, plain_of, station_prefix
from iotad.can.frame import Frame, FrameError


def test_a_station_s_frames_begin_with_its_name_and_python_can_reads_them():
    from can.interfaces.udp_multicast.utils import unpack_message

    prefix = station_prefix("iotad-1234-abcdef")
    for frame in (Frame(0x123, b"\x01\x02\x03"), Frame(0x1ABCDEF, b"\xff" * 8, extended=True), Frame.remote(0x7FF, 4)):
        datagram = pack(prefix, frame)
        assert datagram.startswith(prefix)
        message = unpack_message(datagram, check=True)  # python-can's own reading of it
        assert message.channel == "iotad-1234-abcdef" and Frame.from_can_message(message) == frame


def run_filter(program, packet: bytes) -> int:
    """What a classic BPF program of loads, equality jumps and returns gives for `packet`."""
    pc, a = 0, 0
    while True:
        code, jt, jf, k = program[pc]
        if code & 0x07 == 0x06:
            return k
        if code & 0x07 == 0x00:
            size = {0x00: 4, 0x08: 2, 0x10: 1}[code & 0x18]
            if k + size > len(packet):
                return 0  # the kernel drops a packet read past its end
            a, pc = int.from_bytes(packet[k:k + size], "big"), pc + 1
            continue
        assert code == 0x15
        pc += 1 + (jt if a == k else jf)


@pytest.mark.parametrize("length", [1, 2, 3, 4, 5, 21, 24])
def test_the_socket_filter_drops_exactly_the_datagrams_that_begin_with_the_prefix(length):
    import random

    rng = random.Random(length)
    prefix = bytes(rng.randrange(256) for _ in range(length))
    program = own_frame_filter(prefix)
    header = bytes(8)  # a UDP socket's filter reads from the UDP header on
    assert run_filter(program, header + prefix + b"rest") == 0
    assert run_filter(program, header + prefix) == 0
    for k in range(length):  # one byte different anywhere: kept
        other = bytearray(prefix)
        other[k] ^= 1 << rng.randrange(8)
        assert run_filter(program, header + bytes(other) + b"rest") == 0xFFFFFFFF
    from can.interfaces.udp_multicast.utils import pack_message  # python-can's station: its map begins otherwise

    assert run_filter(program, header + pack_message(Frame(0x10, b"\x01").to_can_message())) == 0xFFFFFFFF


def test_a_datagram_decodes_to_the_value_a_frame_gives():
    import can
    from can.interfaces.udp_multicast.utils import pack_message

    for frame in (Frame(0x123, b"\x01\x02\x03"), Frame(0x1ABCDEF, b"\xff" * 8, extended=True),
                  Frame.remote(0x7FF, 4), Frame(0, b"")):
        assert plain_of(_fields(pack(station_prefix("iotad-1-abcdef"), frame))) == frame.plain()
        assert plain_of(_fields(pack_message(frame.to_can_message()))) == frame.plain()  # python-can's own packing
    error = plain_of(_fields(pack_message(can.Message(arbitration_id=0x004, is_error_frame=True, dlc=8,
                                                      data=bytes(8), is_extended_id=True))))
    assert isinstance(error, can.Message) and error.is_error_frame


@pytest.mark.parametrize("datagram, said", [
    (b"\xc1garbage", "no python-can frame"),
    (b"\x93\x01\x02\x03", "no python-can frame"),
    (pack(station_prefix("s"), Frame(0x10, b"\x01")).replace(b"arbitration_id", b"arbitration_ix"), "does not check"),
])
def test_a_datagram_that_is_no_frame_is_a_frame_error(datagram, said):
    with pytest.raises(FrameError, match=said):
        plain_of(_fields(datagram))


def test_a_standard_id_over_11_bits_is_no_frame():
    import msgpack
    fields = msgpack.unpackb(pack(station_prefix("s"), Frame(0x10, b"\x01")), raw=False)
    fields["arbitration_id"] = 0x800
    with pytest.raises(FrameError, match=r"less than 2\^11"):
        plain_of(fields)


SHARED_BUS = r'''
import json, os, socket, subprocess, sys, time
import can
from iotad.can.bus import open_env_bus
from iotad.can.frame import Frame

group = os.environ["IOTAD_CAN_CHANNEL"]
ipv6 = ":" in group
# an IPv6 group travels on the namespace's own veth pair (tests below): nothing leaves through it
options = {"allow_real_interfaces": True} if ipv6 else {}
theirs = can.Bus(interface="udp_multicast", channel=group, port=43113, hop_limit=1, fd=False)  # python-can's
ours = open_env_bus(**options)

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
them_heard = drain(lambda t: theirs.recv(t))
heard_by_them = [Frame.from_can_message(m) for m in them_heard]
station = ours.bus
try:  # the kernel's filter dropped our frames: nothing waits in our socket
    station._socket.recv(4096, socket.MSG_DONTWAIT)
    queued = True
except BlockingIOError:
    queued = False
# with the filter taken off, the receive loop still drops them, and a second iotad station of this
# process still hears them (it is another station), also one equal to a frame it sent itself
station._socket.setsockopt(socket.SOL_SOCKET, 27, 0)  # SO_DETACH_FILTER
second = open_env_bus(**options)
second.send_frame(sent_by_us[1])
for frame in sent_by_us:
    ours.send_frame(frame)
heard_back = [p for got in drain(lambda t: ours.recv_plain(t, 64)[0]) for p in got]
heard_by_second = [p for got in drain(lambda t: second.recv_plain(t, 64)[0]) for p in got]
second.shutdown()

sent_by_them = [Frame(0x1ABCDE0 + k, bytes([255 - k] * 8), extended=True) for k in range(20)]
sent_by_them.append(sent_by_us[0])  # a frame equal to one of ours, from another station
for frame in sent_by_them:
    theirs.send(frame.to_can_message())
plains, others = [], []
for got in drain(lambda t: ours.recv_plain(t, 64)):
    plains += got[0]
    others += got[1]
# a datagram that is no frame, then a frame: the first is handed back, the second still comes
raw = socket.socket(socket.AF_INET6 if ipv6 else socket.AF_INET, socket.SOCK_DGRAM)
if ipv6:
    raw.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, 1)
else:
    raw.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 1)
raw.sendto(b"\xc1 not msgpack", (group, 43113))
theirs.send(Frame(0x42, b"\x42").to_can_message())
after = drain(lambda t: ours.recv_plain(t, 64))
ours.shutdown(); theirs.shutdown()
print("RESULT " + json.dumps({
    "filtered_in_kernel": station.filtered_in_kernel, "queued": queued, "station": station.station,
    "heard_by_them": [f.plain() for f in heard_by_them], "heard_back": heard_back,
    "heard_by_second": heard_by_second, "their_channels": [m.channel for m in them_heard],
    "plains": plains, "others": [str(o) for o in others],
    "after_plains": [p for got in after for p in got[0]], "after_others": [str(o) for got in after for o in got[1]],
}))
'''


def test_iotad_s_station_and_python_can_s_share_a_bus(can_bus):
    if can_bus.interface != "udp_multicast":
        pytest.skip(f"the tier is {can_bus.name}, which has no udp_multicast station")
    result = can_bus.run_python(SHARED_BUS, timeout=60)
    result.check()
    shared_a_bus(result.output)


# Linux loops no IPv6 multicast back on the loopback (a group there reaches no socket, not even
# another of the same process), so an IPv6 group needs an interface that carries multicast: a
# veth pair made inside the private namespace, both ends kept there, no address beyond their
# link-local ones (DAD off: a tentative address sends nothing for its first second or two).
IPV6_NAMESPACE = ("ip link set lo up && sysctl -qw net.ipv6.conf.default.accept_dad=0 "
                  "&& ip link add can6a type veth peer name can6b && ip link set can6a up && ip link set can6b up")
PYTHON_CAN_IPV6_GROUP = "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173"  # python-can's default udp_multicast channel


def test_they_share_an_ipv6_group_too(tmp_path):
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    if not shutil.which("unshare") or not shutil.which("ip"):
        pytest.skip("`unshare` or `ip` is missing (util-linux, iproute2)")
    probe = subprocess.run(["unshare", "-rn", "sh", "-c", IPV6_NAMESPACE], capture_output=True, text=True, timeout=30)
    if probe.returncode != 0:
        pytest.skip(f"no private network namespace with an IPv6 veth pair here: {(probe.stderr or probe.stdout).strip()}")
    script = tmp_path / "shared_bus.py"
    script.write_text(SHARED_BUS)
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, IOTAD_CAN_INTERFACE="udp_multicast", IOTAD_CAN_CHANNEL=PYTHON_CAN_IPV6_GROUP,
               PYTHONPATH=str(root))
    done = subprocess.run(["unshare", "-rn", "sh", "-c", f'{IPV6_NAMESPACE} && exec "$@"', "iotad-can6",
                           sys.executable, str(script)], capture_output=True, text=True, timeout=60, env=env, cwd=root)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    shared_a_bus(done.stdout)


def shared_a_bus(output: str) -> None:
    """SHARED_BUS's result, as it must be on any group."""
    import json

    line = next(line for line in output.splitlines() if line.startswith("RESULT "))
    got = json.loads(line[len("RESULT "):])
    ours = [Frame(0x10 + k, bytes([k] * (k % 9))) for k in range(20)] + [Frame.remote(0x7FF, 3)]
    theirs = [Frame(0x1ABCDE0 + k, bytes([255 - k] * 8), extended=True) for k in range(20)] + [ours[0]]
    assert got["heard_by_them"] == [f.plain() for f in ours]   # python-can decodes every frame we sent
    assert set(got["their_channels"]) == {got["station"]}       # and sees who sent them
    assert got["filtered_in_kernel"] and not got["queued"]      # ours never reached our socket
    # nor our receive loop, with no filter: only the second station's frame, equal to one of ours
    assert got["heard_back"] == [ours[1].plain()]
    assert got["heard_by_second"] == [f.plain() for f in ours]  # another station of this process hears them
    assert got["plains"] == [f.plain() for f in theirs] and got["others"] == []
    assert got["after_plains"] == [Frame(0x42, b"\x42").plain()]
    assert len(got["after_others"]) == 1 and "no python-can frame" in got["after_others"][0]


def test_a_plain_value_is_sent_as_its_frame_is_and_what_is_no_frame_is_refused():
    """`send_plain` (a node's checked output, packed at once) writes the bytes `send_frame` writes
    for every value, and refuses what a Frame refuses with the Frame's words."""
    import random

    from iotad.can.udp_multicast import UdpMulticastBus

    class Sent(UdpMulticastBus):
        def __init__(self):  # no socket: the datagrams are kept
            self._prefix, self.datagrams = station_prefix("iotad-1-abcdef"), []

        def _send(self, datagram, timeout):
            self.datagrams.append(datagram)

    rng = random.Random(4)
    for _ in range(500):
        extended, rtr = rng.random() < 0.2, rng.random() < 0.1
        dlc = rng.randrange(9)
        frame = (Frame.remote(rng.randrange(0x800), dlc, extended) if rtr else
                 Frame(rng.randrange(0x20000000 if extended else 0x800), bytes(rng.randrange(256) for _ in range(dlc)),
                       extended=extended))
        by_plain, by_frame = Sent(), Sent()
        by_plain.send_plain(frame.plain())
        by_frame.send_frame(frame)
        assert by_plain.datagrams == by_frame.datagrams, frame
    for bad, said in (({"id": 0x800, "extended": False, "rtr": False, "dlc": 0, "data": [0] * 8}, "11-bit"),
                      ({"id": 0x10, "extended": False, "rtr": False, "dlc": 9, "data": [0] * 8}, "dlc must be 0..8")):
        with pytest.raises(FrameError, match=said):
            Sent().send_plain(bad)


def test_an_ipv6_group_with_no_interface_to_carry_it_says_how_to_make_one():
    """A private namespace with only its loopback has nothing that carries IPv6 multicast: opening
    the group is a BusUnavailable naming the veth pair that would, not an OSError, and leaves no
    half-made bus behind."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    if not shutil.which("unshare"):
        pytest.skip("`unshare` is missing (util-linux)")
    opens = ("from iotad.can.bus import BusUnavailable, open_bus\n"
             f"try:\n    open_bus('udp_multicast', {PYTHON_CAN_IPV6_GROUP!r})\n"
             "except BusUnavailable as exc:\n    print('REFUSED', exc)\n")
    done = subprocess.run(["unshare", "-rn", "sh", "-c", 'ip link set lo up && exec "$@"', "iotad-can6",
                           sys.executable, "-c", opens], capture_output=True, text=True, timeout=30,
                          cwd=Path(__file__).resolve().parents[2])
    if done.returncode != 0 and "unshare" in done.stderr:
        pytest.skip(f"no private network namespace here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr[-2000:]
    said = done.stdout
    assert said.startswith(f"REFUSED udp_multicast group [{PYTHON_CAN_IPV6_GROUP}]:43113: "), said
    assert "veth pair" in said and "allow_real_interfaces" in said and "224.0.0.0/4" not in said, said
    assert said.count(PYTHON_CAN_IPV6_GROUP) == 1, said  # the group named once
    assert "not properly shut down" not in done.stderr, done.stderr  # no half-made bus left for python-can to warn of
