"""Opening zenoh sessions the way these machines require: no multicast scouting, explicit
loopback (or system-file) endpoints. Every zenoh session in iotad comes from here."""
from __future__ import annotations

import json
import socket
from typing import Iterable

import zenoh

from iotad.machine.certificates import TlsFiles, from_env as tls_from_env
from iotad.node_host.credentials import Credentials, for_endpoints, from_env

DEFAULT_LISTEN = ("tcp/127.0.0.1:0",)  # port 0: the OS picks a free loopback port
# Where `iotad run` puts its hub peer unless told otherwise, and where the introspection commands
# (`iotad ls/echo/pub/hz`) look for a running system by default.
DEFAULT_HUB_ENDPOINT = "tcp/127.0.0.1:7447"


def reachable(endpoint: str) -> str:
    """Where a client on this host reaches a hub listening on `endpoint` (on every interface: on
    loopback)."""
    return endpoint.replace("0.0.0.0", "127.0.0.1")


# What a socket toward another host may hold unsent (bytes asked; Linux grants twice as much). A
# zenoh TLS link's socket had 3.9 MB (`ss -tm`): 30 s of a link slowed to 1 Mbit/s, out of reach
# of zenoh's priorities and of its DROP across hosts. 32 KB is 0.26 s of such a link, and on a
# LAN (RTT ~0.2 ms) still ~150 MB/s.
CROSS_HOST_SNDBUF = 16384


def bounded_send_buffer(endpoints: Iterable[str]) -> list[str]:
    """`endpoints`, each tcp/ or tls/ one that may reach another host (not loopback) with zenoh's
    `so_sndbuf` endpoint setting, unless it has one. The endpoint's own config (after '#') is the
    only way zenoh 1.10 takes it for TLS links: `transport/link/tcp/so_sndbuf` applies to TCP
    links only (measured with `ss -tm`)."""
    out = []
    for endpoint in endpoints:
        protocol, _, address = _parts(endpoint)
        host = address.rpartition(":")[0].strip("[]")
        if protocol in ("tcp", "tls") and host not in ("127.0.0.1", "localhost", "::1") \
                and "so_sndbuf=" not in endpoint:
            endpoint += (";" if "#" in endpoint else "#") + f"so_sndbuf={CROSS_HOST_SNDBUF}"
        out.append(endpoint)
    return out


def _parts(endpoint: str) -> tuple[str, str, str]:
    """(protocol, "/" or "", address) of an endpoint: its metadata and config are zenoh's business."""
    protocol, slash, rest = endpoint.partition("/")
    return protocol, slash, rest.split("?", 1)[0].split("#", 1)[0]


def endpoint_problem(text: object) -> str:
    """Why `text` is not a zenoh endpoint such as tcp/127.0.0.1:7447 ("" when it is one): checked
    before zenoh sees it, so that zenoh's own error (a Rust source path) never reaches the user."""
    if not isinstance(text, str):
        return f"expected a zenoh endpoint PROTOCOL/ADDRESS:PORT such as tcp/127.0.0.1:7447, got {text!r}"
    protocol, slash, address = _parts(text)
    ip = protocol in ("tcp", "udp", "tls", "quic")
    if not slash or not protocol or not address or (ip and not address.rpartition(":")[2].isdigit()):
        return f"expected a zenoh endpoint PROTOCOL/ADDRESS:PORT such as tcp/127.0.0.1:7447, got {text!r}"
    if ip and int(address.rpartition(":")[2]) > 65535:
        return f"port out of range in {text!r} (0-65535)"
    return ""


def make_config(listen: Iterable[str] = DEFAULT_LISTEN, connect: Iterable[str] = (), mode: str = "peer",
                extra: dict | None = None, credentials: Credentials | None = None,
                tls: TlsFiles | None = None) -> zenoh.Config:
    """`extra` maps zenoh config paths (e.g. "transport/link/tx/queue/size/data") to JSON values;
    it cannot turn multicast scouting back on. `credentials`: authenticate with zenoh's
    user-password scheme (and, with a dictionary, check the peers that connect here). `tls`: the
    certificates for `tls/` endpoints, with mutual authentication (iotad/machine/certificates.py).
    Every endpoint that may reach another host gets a bounded socket send buffer
    (`bounded_send_buffer`): a launcher's, and a node's of an open run, which links across hosts
    itself."""
    listen, connect = bounded_send_buffer(listen), bounded_send_buffer(connect)
    config = zenoh.Config()
    for path, value in (extra or {}).items():
        config.insert_json5(path, json.dumps(value))
    if credentials is not None:
        config.insert_json5("transport/auth/usrpwd", json.dumps(credentials.zenoh_usrpwd()))
    if tls is not None:
        config.insert_json5("transport/link/tls", json.dumps(tls.zenoh_tls()))
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    return config


def open_session(listen: Iterable[str] = DEFAULT_LISTEN, connect: Iterable[str] = (), mode: str = "peer",
                 connect_timeout: float | None = None, extra: dict | None = None,
                 credentials: Credentials | None | bool = None, tls: TlsFiles | None = None) -> zenoh.Session:
    """A zenoh session; close it (or use `with`) or the interpreter hangs at exit.

    With `connect_timeout` (seconds), opening fails with `zenoh.ZError` when no `connect`
    endpoint answers in time; without it a peer keeps retrying in the background, which is what
    a node wants (its hub may start later) but not what a command-line tool wants.

    `credentials` None: those the launcher gave this process in `IOTAD_CREDENTIALS`, if any; a
    process given credentials (these, or explicit ones without the hub's dictionary) is a client
    of the hub that listens nowhere, so that everything it sends passes the hub's access control
    (a listening peer could be reached around it). False: none, whatever the environment says.

    `tls` None: the certificates this process was given in `IOTAD_CERTS`/`IOTAD_CERTS_HOST`, if
    any (iotad/machine/certificates.py): used on `tls/` endpoints."""
    if tls is None:
        tls = tls_from_env()
    if credentials is None:
        credentials = from_env()
        if credentials is None and connect:
            # a hub that this user's `iotad run` guards lets in its tools' user (read only)
            credentials = for_endpoints(connect)
            given = False
        else:
            given = credentials is not None
    else:
        given = bool(credentials) and credentials.dictionary is None
    if given:  # a user of the hub (not the hub itself): everything it does crosses the hub's rules
        mode, listen = "client", ()
    config = make_config(listen, connect, mode, extra, credentials or None, tls)
    if connect_timeout is not None and list(connect):
        config.insert_json5("connect/timeout_ms", json.dumps(max(1, int(connect_timeout * 1000))))
        config.insert_json5("connect/exit_on_failure", "true")
    return zenoh.open(config)


def free_port(host: str = "127.0.0.1") -> int:
    """A loopback TCP port free right now, for a hub endpoint the launcher hands to its nodes."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]


class PeerUnreachable(ConnectionError):
    """No zenoh peer answered at the endpoints a tool was told to connect to."""


def open_tool_session(connect: Iterable[str] = (DEFAULT_HUB_ENDPOINT,), timeout: float = 3.0) -> zenoh.Session:
    """A session for a command-line tool (`iotad ls/echo/pub/hz`): a client of the hub, which
    relays for its clients at once (a peer would first have to be meshed by gossip with every
    node, and its first query could miss them). Fails within `timeout` seconds with
    `PeerUnreachable` (one clear line) instead of retrying forever when nothing runs there."""
    endpoints = list(connect)
    try:
        # a system under access control (docs/access-control.md) lets in only known users
        return open_session((), endpoints, mode="client", connect_timeout=timeout,
                            credentials=for_endpoints(endpoints) or False)
    except zenoh.ZError as exc:
        reason = str(exc).split(" at ", 1)[0].strip()
        raise PeerUnreachable(f"no zenoh peer at {', '.join(endpoints)} ({reason}); is a system running? "
                              "Use --connect ENDPOINT to name its hub; a hub under access control admits only the users "
                              "its 'iotad run' made (docs/access-control.md)") from None
