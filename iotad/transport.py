"""Opening zenoh sessions the way these machines require: no multicast scouting, explicit
loopback (or system-file) endpoints. Every zenoh session in iotad comes from here."""
from __future__ import annotations

import json
import socket
from typing import Iterable

import zenoh

DEFAULT_LISTEN = ("tcp/127.0.0.1:0",)  # port 0: the OS picks a free loopback port


def make_config(listen: Iterable[str] = DEFAULT_LISTEN, connect: Iterable[str] = (), mode: str = "peer") -> zenoh.Config:
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return config


def open_session(listen: Iterable[str] = DEFAULT_LISTEN, connect: Iterable[str] = (), mode: str = "peer") -> zenoh.Session:
    """A zenoh session; close it (or use `with`) or the interpreter hangs at exit."""
    return zenoh.open(make_config(listen, connect, mode))


def free_port(host: str = "127.0.0.1") -> int:
    """A loopback TCP port free right now, for a hub endpoint the launcher hands to its nodes."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]
