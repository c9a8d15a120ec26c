"""`open_bus`: a CAN bus of real time by interface name: python-can's BusABC, and `Frame`s too.

    with open_bus("socketcan", "vcan0") as bus:
        bus.send(odrive.encode(3, "Estop"))     # a Frame, or a can.Message
        message = bus.recv(timeout=0.1)         # a can.Message, or None after the timeout (BusABC)
        got = bus.recv_frame(timeout=0.1)       # (time, Frame), or None

Interfaces: `socketcan` (a Linux CAN device: vcan0, can0), `udp_multicast` (an IP multicast group
standing for a bus, allowed only inside a private network namespace), `virtual` (python-can's
in-process bus, for one process). Every `RealTimeBus` is the same small interface, python-can's
BusABC (`send`, `recv`, `fileno`, `shutdown`), plus `send_frame`/`recv_frame`, a `name` and
`describe()`. A bus never hands back a frame it sent itself. `udp_multicast` is iotad's own
station (`iotad.can.udp_multicast`) on python-can's wire format: the two share a bus.
Failures to open say why and what to do (`BusUnavailable`). The interface name `env` (no
channel) opens the bus the environment names, as `open_env_bus` does.
"""
from __future__ import annotations

import errno
import os
import socket
import time

from .frame import Frame, FrameError

INTERFACES = ("socketcan", "udp_multicast", "virtual")
ENV = "env"  # not an interface: "the bus the environment names" (a tier's IOTAD_CAN_INTERFACE/CHANNEL)
UDP_GROUP = "239.74.163.2"   # the project's IPv4 group for udp_multicast buses
UDP_PORT = 43113

VIRTUAL_CHANNEL = "iotad"

ENV_INTERFACE, ENV_CHANNEL, ENV_TIER = "IOTAD_CAN_INTERFACE", "IOTAD_CAN_CHANNEL", "IOTAD_CAN_TIER"

TIER_HINT = ("run it with a CAN bus: `python -m iotad.can.tiers run -- CMD...` (vcan0 in a private "
             "network namespace, or in user-mode Linux where the kernel has no CAN; docs/can.md)")


class BusUnavailable(RuntimeError):
    """A bus that cannot be opened here; the message says why and what to do instead."""


class RealTimeBus:
    """One open CAN bus with python-can's BusABC interface (`send(msg)`, `recv(timeout)` of
    `can.Message`s, `fileno`, `shutdown`), plus `send_frame`/`recv_frame` in `Frame`s and
    `send_plain`/`recv_plain` in plain `canFrame` values, what a node's CAN port moves. `send` takes a `Frame` too. Never hands back a
    frame it sent itself (udp_multicast's own station drops them: `iotad.can.udp_multicast`)."""

    def __init__(self, bus, interface: str, channel: str):
        self.bus = bus                   # the python-can BusABC underneath
        self.interface, self.channel = interface, channel
        self.name = f"{interface}:{channel}"
        self.sent = self.received = 0
        # a bus that can send a Frame and hand over plain values without a can.Message
        # (iotad's udp_multicast station) is asked directly: a control loop sends and hears
        # thousands of frames a second
        self._send_frame = getattr(bus, "send_frame", None)
        self._recv_plain = getattr(bus, "recv_plain", None)
        self._send_plain = getattr(bus, "send_plain", None)

    def describe(self) -> str:
        return f"{self.interface} bus on {self.channel}"

    def send(self, msg, timeout: float | None = None) -> None:
        """Send a `can.Message` or a `Frame`."""
        if isinstance(msg, Frame):
            self.send_frame(msg, timeout)
            return
        if not hasattr(msg, "arbitration_id"):
            raise FrameError(f"send needs a can.Message or a Frame, got {type(msg).__name__} {msg!r}")
        self.bus.send(msg, timeout=timeout)
        self.sent += 1

    def recv(self, timeout: float | None = None):
        """The next `can.Message` from another station, or None after `timeout` s (None: wait)."""
        message = self.bus.recv(timeout=timeout)
        if message is not None:
            self.received += 1
        return message

    def send_frame(self, frame: Frame, timeout: float | None = None) -> None:
        if not isinstance(frame, Frame):
            raise FrameError(f"send_frame needs a Frame, got {type(frame).__name__} {frame!r}")
        if self._send_frame is not None:
            self._send_frame(frame, timeout)
        else:
            self.bus.send(frame.to_can_message(), timeout=timeout)
        self.sent += 1

    def send_plain(self, value) -> None:
        """Send a `canFrame` value (a plain dict, or a record); FrameError for what is no frame."""
        if self._send_plain is not None and value.__class__ is dict:
            self._send_plain(value)
            self.sent += 1
        else:
            self.send_frame(Frame.from_value(value))

    def recv_frame(self, timeout: float | None = None) -> tuple[float, Frame] | None:
        """(receive time, Frame) of the next classic frame from another station, or None after
        `timeout`; error frames and CAN FD frames are skipped."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            message = self.recv(left)
            if message is None:
                return None
            try:
                return message.timestamp, Frame.from_can_message(message)
            except FrameError:
                continue

    def recv_plain(self, timeout: float | None, limit: int) -> tuple[list[dict], list]:
        """Up to `limit` things other stations sent: the first within `timeout` s (None: wait),
        then what the bus already holds. (plain canFrame values, in order; the rest, in order:
        can.Messages of error frames and CAN FD frames, FrameErrors of what is no frame.)"""
        if self._recv_plain is not None:
            frames, others = self._recv_plain(timeout, limit)
        else:
            frames, others = [], []
            message = self.bus.recv(timeout=timeout)
            while message is not None:
                try:
                    frames.append(Frame.from_can_message(message).plain())
                except FrameError:
                    others.append(message)
                if len(frames) + len(others) >= limit:
                    break
                message = self.bus.recv(timeout=0)
        self.received += len(frames)
        return frames, others

    def fileno(self) -> int:
        return self.bus.fileno()

    def shutdown(self) -> None:
        self.bus.shutdown()

    def __enter__(self) -> "RealTimeBus":
        return self

    def __exit__(self, *exc) -> None:
        self.shutdown()

    def __repr__(self) -> str:
        return f"<RealTimeBus {self.name}>"


def open_bus(interface: str, channel: str | None = None, **kw) -> RealTimeBus:
    """Open a bus by python-can interface name. Extra keywords go to python-can's bus
    (e.g. `bitrate`, `port`; None values are dropped). `udp_multicast` refuses to run where the
    network has real interfaces."""
    kw = {key: value for key, value in kw.items() if value is not None}
    if interface == ENV:  # a system file that runs unchanged on every tier (docs/system-file.md)
        if channel:
            raise BusUnavailable(f"interface {ENV!r} takes the channel from {ENV_CHANNEL} too: give no channel")
        return open_env_bus(**kw)
    if interface not in INTERFACES:
        raise BusUnavailable(f"unknown CAN interface {interface!r}; choose one of {', '.join(INTERFACES)}")
    import can

    if interface == "socketcan":
        channel = channel or "vcan0"
        _check_socketcan(channel)
        try:
            bus = can.Bus(interface="socketcan", channel=channel, receive_own_messages=False, **kw)
        except OSError as exc:
            raise BusUnavailable(f"socketcan {channel}: {exc}") from None
        return RealTimeBus(bus, interface, channel)
    if interface == "udp_multicast":
        channel = channel or UDP_GROUP
        real = real_interfaces()
        if real and not kw.pop("allow_real_interfaces", False):
            raise BusUnavailable(
                f"udp_multicast would put CAN frames on real network interfaces ({', '.join(real)}); run in a "
                f"private network namespace: `python -m iotad.can.tiers run --tier udp_multicast -- CMD...`")
        kw.pop("allow_real_interfaces", None)
        kw.setdefault("port", UDP_PORT)
        kw.setdefault("hop_limit", 1)
        kw.setdefault("fd", False)
        kw.pop("bitrate", None)  # a multicast group has no bit rate (python-can ignores it too)
        from .udp_multicast import UdpMulticastBus

        try:
            bus = UdpMulticastBus(channel, **kw)
        except (OSError, can.CanError) as exc:
            said = str(exc) if isinstance(exc, can.CanInitializationError) else f"udp_multicast group {channel}: {exc}"
            raise BusUnavailable(f"{said}; {_namespace_hint(channel)}") from None  # (the station's own errors name the group)
        return RealTimeBus(bus, interface, channel)
    channel = channel or VIRTUAL_CHANNEL
    bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False, **kw)
    return RealTimeBus(bus, interface, channel)


def _namespace_hint(group: str) -> str:
    """How a private network namespace carries `group` (IPv4, or IPv6: Linux loops no IPv6
    multicast back on the loopback, so it needs an interface of its own that stays inside)."""
    if ":" in group:
        return ("an IPv6 group needs an interface that carries multicast, which Linux's loopback does not for "
                "IPv6: in a private network namespace, a veth pair kept inside it (`ip link add can6a type veth "
                "peer name can6b`, both set up, `sysctl net.ipv6.conf.default.accept_dad=0` before), and the bus "
                "opened with allow_real_interfaces")
    return ("in a private network namespace the loopback needs multicast and a route: `ip link set lo up && "
            "ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo`")


def env_bus() -> tuple[str, str | None] | None:
    """(interface, channel) of the bus the environment names (IOTAD_CAN_INTERFACE, IOTAD_CAN_CHANNEL),
    or None where IOTAD_CAN_INTERFACE is not set."""
    interface = os.environ.get(ENV_INTERFACE)
    return (interface, os.environ.get(ENV_CHANNEL) or None) if interface else None


def open_env_bus(**kw) -> RealTimeBus:
    """The bus a tier gives a command (`python -m iotad.can.tiers run`): IOTAD_CAN_INTERFACE and
    IOTAD_CAN_CHANNEL name it."""
    interface = os.environ.get(ENV_INTERFACE)
    if not interface:
        raise BusUnavailable(f"{ENV_INTERFACE} is not set: this command was not started with a CAN bus; {TIER_HINT}")
    return open_bus(interface, os.environ.get(ENV_CHANNEL) or None, **kw)


def _check_socketcan(channel: str) -> None:
    """Say clearly why socketcan cannot work here, before python-can says 'errno 97'."""
    family = getattr(socket, "AF_CAN", None)
    if family is None:
        raise BusUnavailable(f"socketcan is not available on this platform (Python has no AF_CAN); {TIER_HINT}")
    try:
        probe = socket.socket(family, socket.SOCK_RAW, socket.CAN_RAW)
    except OSError as exc:
        if exc.errno in (errno.EAFNOSUPPORT, errno.EPROTONOSUPPORT):
            raise BusUnavailable(f"socketcan is not available on this kernel (no AF_CAN: {exc.strerror}); "
                                 f"{TIER_HINT}") from None
        raise BusUnavailable(f"socketcan: cannot open a CAN socket: {exc}") from None
    probe.close()
    if channel not in interface_names():
        raise BusUnavailable(f"no CAN device {channel!r} here; create a virtual one with `ip link add dev {channel} "
                             f"type vcan && ip link set up {channel}` (root, or inside `unshare -rn`), or {TIER_HINT}")


def interface_names() -> list[str]:
    """Network interfaces of this process's network namespace (not /sys, which shows the
    namespace that mounted it)."""
    try:
        return [name for _, name in socket.if_nameindex()]
    except OSError:
        return []


def real_interfaces() -> list[str]:
    """Network interfaces other than loopback that are up (where multicast could leave the host)."""
    import fcntl
    import struct

    found = []
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        for name in interface_names():
            if name == "lo":
                continue
            try:
                request = struct.pack("16sh", name.encode()[:15], 0)
                flags = struct.unpack("16sh", fcntl.ioctl(probe, 0x8913, request)[:18])[1]  # SIOCGIFFLAGS
            except OSError:
                flags = 1  # cannot tell: count it as up
            if flags & 0x1:  # IFF_UP
                found.append(name)
    return found


BusLike = RealTimeBus  # the name the robot interfaces use for what open_bus returns
