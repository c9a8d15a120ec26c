"""`UdpMulticastBus`: a CAN bus on an IP multicast group, on python-can's `udp_multicast` wire
format (one msgpack map per frame, as `can.interfaces.udp_multicast.utils.pack_message` writes it),
so that it and python-can's own bus are stations of one bus.

Why our own station rather than python-can's: a motor node with six joints at 500 Hz hears 6,000
datagrams a second, half of them its own frames coming back (multicast loopback cannot be refused
per socket). python-can's bus waits in `select` before each datagram, reads its kernel timestamp,
and builds a fully checked `can.Message` of it, which the node then dropped (its own) or turned
into a `canFrame` value; that was most of the node's CPU (docs/can.md, "Benchmark"). This bus:

- never hears its own frames: each station names itself in every frame it sends (the `channel`
  field of python-can's map, written first: `iotad-<pid>-<6 random hex digits>`, which python-can
  shows as the message's channel), and a socket filter (classic BPF, `SO_ATTACH_FILTER`) drops the
  datagrams that begin so in the kernel, before they wake the receiving thread; where no filter
  can be attached, the same test is made on each datagram's first bytes;
- drains what the socket holds without a wait per datagram (`recv_plain`), and decodes each into
  the plain `canFrame` value an IOTA takes, with the checks a `Frame` makes;
- is python-can's `BusABC` too (`send`, `recv`, `shutdown`, `fileno`), for the tools that want
  `can.Message`s (candump, scans); that path keeps python-can's kernel receive timestamps.

A datagram that is no frame (not msgpack, a key missing, an id too long for its kind) is handed
back as a `FrameError`, to be recorded, never raised out of the receive loop.
"""
from __future__ import annotations

import errno
import os
import select
import socket
import struct
import time

import can
import msgpack

from .frame import EXTENDED_ID_MAX, STANDARD_ID_MAX, Frame, FrameError

SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
MAX_DATAGRAM = 4096       # python-can's frames are under 200 bytes; anything longer is no frame
RECEIVE_BUFFER = 1 << 20  # bytes the kernel may hold for us: about a thousand frames, some 0.15 s of a busy bus

_PADDING = [[0] * n for n in range(9)]  # zero bytes that pad a frame's data to 8, by how many


def station_prefix(name: str) -> bytes:
    """The first bytes of every frame a station named `name` sends: a map of python-can's 11 keys
    whose first is its `channel`, the station's name."""
    return b"\x8b" + msgpack.packb("channel") + msgpack.packb(name)


def pack(prefix: bytes, frame: Frame) -> bytes:
    """A frame as python-can's udp_multicast carries it (the keys of its `pack_message`), sent by
    the station whose `station_prefix` is `prefix`."""
    return _packed(prefix, frame.id, frame.extended, frame.rtr, len(frame.data), frame.data)


def pack_message(prefix: bytes, message: can.Message) -> bytes:
    return _packed(prefix, message.arbitration_id, message.is_extended_id, message.is_remote_frame, message.dlc,
                   bytes(message.data), message.timestamp, message.is_error_frame, message.is_fd,
                   message.bitrate_switch, message.error_state_indicator)


def _packed(prefix: bytes, ident: int, extended: bool, rtr: bool, dlc: int, data: bytes, timestamp: float = 0.0,
            error: bool = False, fd: bool = False, brs: bool = False, esi: bool = False) -> bytes:
    return prefix + msgpack.packb({
        "timestamp": timestamp, "arbitration_id": ident, "is_extended_id": extended, "is_remote_frame": rtr,
        "is_error_frame": error, "dlc": dlc, "data": data, "is_fd": fd, "bitrate_switch": brs,
        "error_state_indicator": esi,
    }, use_bin_type=True)[1:]  # a map of the 10 other keys, less its own header (the prefix's says 11)


def own_frame_filter(prefix: bytes) -> list[tuple[int, int, int, int]]:
    """A classic BPF program (code, jt, jf, k per instruction) for a UDP socket that drops the
    datagrams beginning with `prefix` and keeps every other. A UDP socket's filter sees the
    datagram from its 8-byte UDP header on."""
    chunks, at = [], 0
    while at < len(prefix):
        size = 4 if len(prefix) - at >= 4 else 2 if len(prefix) - at >= 2 else 1
        chunks.append((at, size, int.from_bytes(prefix[at:at + size], "big")))
        at += size
    program = []
    for k, (at, size, value) in enumerate(chunks):
        load = {4: _BPF_W, 2: _BPF_H, 1: _BPF_B}[size]
        program.append((_BPF_LD | load | _BPF_ABS, 0, 0, _UDP_HEADER + at))
        # equal: on to the next chunk; different: to the last instruction, which keeps it
        program.append((_BPF_JMP | _BPF_JEQ | _BPF_K, 0, 2 * (len(chunks) - k - 1) + 1, value))
    program.append((_BPF_RET | _BPF_K, 0, 0, 0))           # every byte ours: drop it
    program.append((_BPF_RET | _BPF_K, 0, 0, 0xFFFFFFFF))  # keep it whole
    return program


_BPF_LD, _BPF_W, _BPF_H, _BPF_B, _BPF_ABS = 0x00, 0x00, 0x08, 0x10, 0x20
_BPF_JMP, _BPF_JEQ, _BPF_K, _BPF_RET = 0x05, 0x10, 0x00, 0x06
_UDP_HEADER = 8
SO_ATTACH_FILTER = getattr(socket, "SO_ATTACH_FILTER", 26)


def attach_filter(sock: socket.socket, program: list[tuple[int, int, int, int]]) -> bool:
    """Attach a classic BPF program to `sock`; False where the kernel or platform has none."""
    import ctypes

    code = ctypes.create_string_buffer(b"".join(struct.pack("HBBI", *instruction) for instruction in program))
    try:  # struct sock_fprog {unsigned short len; struct sock_filter *filter;}; the kernel copies it
        sock.setsockopt(socket.SOL_SOCKET, SO_ATTACH_FILTER,
                        struct.pack("HP", len(program), ctypes.addressof(code)))
    except OSError:
        return False
    return True


def _fields(datagram: bytes) -> dict:
    try:
        fields = msgpack.unpackb(datagram, raw=False)
    except Exception as exc:  # noqa: BLE001 - msgpack raises several kinds for bytes that are no map
        raise FrameError(f"a datagram of {len(datagram)} bytes that is no python-can frame ({exc})") from None
    if not isinstance(fields, dict):
        raise FrameError(f"a datagram that is no python-can frame: {fields!r:.80}")
    return fields


def message_of(fields: dict, timestamp: float = 0.0) -> can.Message:
    """The can.Message of a datagram's fields, checked as python-can checks what it receives."""
    unknown = sorted(str(key) for key in fields if key not in _MESSAGE_FIELDS and key != "timestamp")
    missing = [key for key in _REQUIRED if key not in fields]
    if unknown or missing:
        raise FrameError(f"a python-can frame that does not check: "
                         f"{'unknown ' + ', '.join(unknown) if unknown else ''}"
                         f"{'; ' if unknown and missing else ''}{'missing ' + ', '.join(missing) if missing else ''}")
    known = {key: value for key, value in fields.items() if key != "timestamp"}
    known["timestamp"] = timestamp
    try:
        return can.Message(check=True, **known)
    except (TypeError, ValueError) as exc:
        raise FrameError(f"a python-can frame that does not check: {exc}") from None


_MESSAGE_FIELDS = ("arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame", "channel", "dlc",
                   "data", "is_fd", "bitrate_switch", "error_state_indicator")
_REQUIRED = ("arbitration_id", "is_extended_id", "dlc", "data")  # python-can would take a missing one as 0


def plain_of(fields: dict):
    """The plain `canFrame` value of a datagram's fields ({id, extended, rtr, dlc, data}, data
    zero-padded to 8), or the can.Message of an error frame or a CAN FD frame, which no IOTA takes.
    Raises FrameError for what is no frame."""
    ident, extended, rtr = fields.get("arbitration_id"), fields.get("is_extended_id"), fields.get("is_remote_frame")
    dlc, data = fields.get("dlc"), fields.get("data")
    # the usual frame, checked in one go: the same checks `Frame` makes
    if (ident.__class__ is int and extended.__class__ is bool and rtr.__class__ is bool and dlc.__class__ is int
            and data.__class__ is bytes and not fields.get("is_error_frame") and not fields.get("is_fd")
            and 0 <= ident <= (EXTENDED_ID_MAX if extended else STANDARD_ID_MAX)):
        if rtr:
            if 0 <= dlc <= 8 and not any(data):
                return {"id": ident, "extended": extended, "rtr": True, "dlc": dlc, "data": [0] * 8}
        elif dlc == len(data) <= 8:
            return {"id": ident, "extended": extended, "rtr": False, "dlc": dlc, "data": [*data, *_PADDING[8 - dlc]]}
    message = message_of(fields)  # anything else, said as python-can and `Frame` say it
    if message.is_error_frame or message.is_fd:
        return message
    return Frame.from_can_message(message).plain()


class UdpMulticastBus(can.BusABC):
    """One station on a multicast group standing for a CAN bus. `channel` is the group (IPv4 or
    IPv6), `port` the UDP port, `hop_limit` the multicast TTL (1: never past this host's
    routers). Classic CAN only (`fd` must be False). Never hands back a frame it sent."""

    def __init__(self, channel: str, port: int, hop_limit: int = 1, fd: bool = False, **kwargs):
        if fd:
            raise can.CanInterfaceNotImplementedError("iotad's udp_multicast bus carries classic CAN only")
        # the socket before BusABC's state: a group that cannot be opened leaves no bus behind that
        # python-can would warn was "not properly shut down"
        self._socket = _open_socket(channel, port, hop_limit)
        super().__init__(channel, **kwargs)
        self.channel_info = f"udp_multicast {channel}:{port}"
        self._destination = (channel, port)
        self._poll = select.poll()
        self._poll.register(self._socket, select.POLLIN)
        # what python-can shows as our frames' channel: a process id is unique on a host at a time,
        # and the random part tells two stations of one process apart
        self.station = f"iotad-{os.getpid()}-{os.urandom(3).hex()}"
        self._prefix = station_prefix(self.station)
        self.filtered_in_kernel = attach_filter(self._socket, own_frame_filter(self._prefix))
        self._can_protocol = can.CanProtocol.CAN_20

    # --- sending ---------------------------------------------------------------------------

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.is_fd:
            raise can.CanOperationError("cannot send a CAN FD frame on a classic CAN bus")
        self._send(pack_message(self._prefix, msg), timeout)

    def send_frame(self, frame: Frame, timeout: float | None = None) -> None:
        self._send(pack(self._prefix, frame), timeout)

    def send_plain(self, value: dict) -> None:
        """Send a `canFrame` plain value (what a node's output carries, checked against the
        type: id, dlc, 8 data bytes in range), without making a Frame of it first; anything a
        Frame would refuse (an 11-bit id past 0x7FF, a remote frame with data) goes by
        `Frame.from_value`, which says why (FrameError)."""
        ident, extended, rtr, dlc, data = value["id"], value["extended"], value["rtr"], value["dlc"], value["data"]
        if (extended is False and rtr is False and ident.__class__ is int and 0 <= ident <= STANDARD_ID_MAX
                and dlc.__class__ is int and 0 <= dlc <= 8 and data.__class__ is list and len(data) == 8):
            self._send(_packed(self._prefix, ident, False, False, dlc, bytes(data[:dlc])), None)
            return
        self.send_frame(Frame.from_value(value))

    def _send(self, datagram: bytes, timeout: float | None) -> None:
        try:
            if timeout is not None and not select.select([], [self._socket], [], timeout)[1]:
                raise can.CanTimeoutError(f"the socket took no frame within {timeout} s")
            self._socket.sendto(datagram, self._destination)
        except OSError as exc:
            raise can.CanOperationError(f"failed to send on {self.channel_info}: {exc}") from exc

    # --- receiving -------------------------------------------------------------------------

    def recv_plain(self, timeout: float | None, limit: int) -> tuple[list[dict], list]:
        """Up to `limit` things another station sent, waiting at most `timeout` s (None: for
        ever) for the first and not at all for the rest: (the plain canFrame values, in order;
        the rest, in order: can.Messages of error and CAN FD frames, FrameErrors of datagrams
        that are no frame)."""
        frames, others = [], []
        sock, own, flags = self._socket, self._prefix, socket.MSG_DONTWAIT
        waited = False
        while len(frames) + len(others) < limit:
            try:
                datagram = sock.recv(MAX_DATAGRAM, flags)
            except BlockingIOError:
                if waited or frames or others:
                    break
                waited = True
                if not self._poll.poll(None if timeout is None else max(0, int(timeout * 1000 + 0.999))):
                    break
                continue
            if datagram.startswith(own):  # ours, where no socket filter dropped it
                continue
            try:
                got = plain_of(_fields(datagram))
            except FrameError as exc:
                others.append(exc)
                continue
            (frames if got.__class__ is dict else others).append(got)
        return frames, others

    def _recv_internal(self, timeout: float | None):
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not self._poll.poll(None if left is None else int(left * 1000 + 0.999)):
                return None, False
            try:
                datagram, ancillary, _, _ = self._socket.recvmsg(MAX_DATAGRAM, socket.CMSG_SPACE(16),
                                                                 socket.MSG_DONTWAIT)
            except BlockingIOError:
                continue
            if datagram.startswith(self._prefix):
                continue
            timestamp = time.time()
            for level, kind, data in ancillary:
                if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= 16:
                    seconds, nanoseconds = struct.unpack("@ll", data[:16])
                    timestamp = seconds + nanoseconds * 1e-9
            try:
                return message_of(_fields(datagram), timestamp), False
            except FrameError as exc:
                raise can.CanOperationError(f"could not unpack a received frame: {exc}") from None

    def fileno(self) -> int:
        return self._socket.fileno()

    def shutdown(self) -> None:
        super().shutdown()
        self._socket.close()


def _open_socket(group: str, port: int, hop_limit: int) -> socket.socket:
    """A UDP socket bound to `port`, a member of `group`, as python-can's bus opens one (so both
    share the port: SO_REUSEADDR and SO_REUSEPORT), with kernel receive timestamps."""
    try:
        family = socket.getaddrinfo(group, port, type=socket.SOCK_DGRAM)[0][0]
    except socket.gaierror as exc:
        raise can.CanInitializationError(f"udp_multicast group {group!r}: {exc}") from None
    sock = socket.socket(family, socket.SOCK_DGRAM)
    try:
        ttl = struct.pack("@I", hop_limit)
        if family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
        else:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_MULTICAST_HOPS, ttl)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        try:  # the kernel caps it at net.core.rmem_max, silently
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.EINVAL):
                raise
        sock.bind(("", port))
        member = socket.inet_pton(family, group)
        if family == socket.AF_INET:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, member + struct.pack("@I", socket.INADDR_ANY))
        else:
            sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_JOIN_GROUP, member + struct.pack("@I", 0))
    except OSError as exc:
        sock.close()
        where = f"[{group}]:{port}" if family == socket.AF_INET6 else f"{group}:{port}"  # an IPv6 group has colons
        raise can.CanInitializationError(f"udp_multicast group {where}: {exc}") from exc
    return sock
