"""ROS 2 machines inside the trust boundary: what `iotad certs ros2 NAME` writes for one (its
certificate and key from the system's authority, and a zenoh session configuration for rmw_zenoh,
`ZENOH_SESSION_CONFIG_URI`, with TLS to the hub and its own user and password), and the users the
hub of `iotad run --certs DIR` admits for them, each with the rights the `[[ros2]]` tables give a
ROS 2 peer (`iotad.ros2.rights.peer_rights`): subscribe to the out topics, publish on the in
topics, the graph's liveliness keys, nothing else (docs/ros2.md).

A peer's password is derived from the authority's key (HMAC-SHA256 of its name, as a host's
agent secret is, under another label), so the hub, which holds `ca.key`, needs no list of
passwords: every `ros2-NAME.json5` in the certificates' folder is a peer it admits.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import re
from pathlib import Path
from typing import Any

from iotad.machine.certificates import AUTHORITY_CERTIFICATE, AUTHORITY_KEY, CertificateError, issue_host

PREFIX = "ros2-"
SUFFIX = ".json5"
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,56}$")


def peer_user(name: str) -> str:
    """The user name (and the certificate's name) of ROS 2 peer `name` on the hub."""
    return f"{PREFIX}{name}"


def config_path(directory: str | Path, name: str) -> Path:
    return Path(directory) / f"{peer_user(name)}{SUFFIX}"


def password(directory: str | Path, name: str) -> str:
    """Peer `name`'s password, from the authority's key in `directory`."""
    try:
        key = (Path(directory) / AUTHORITY_KEY).read_bytes()
    except OSError:
        raise CertificateError(f"no authority's key {Path(directory) / AUTHORITY_KEY}: a ROS 2 peer's password "
                               "is derived from it (keep the peers' files where the authority is)") from None
    return hmac.new(key, f"iotad ros2 peer {name}".encode(), hashlib.sha256).hexdigest()


def peers(directory: str | Path | None) -> list[str]:
    """The ROS 2 peers `iotad certs ros2` made in `directory`: those the hub admits."""
    if directory is None:
        return []
    names = []
    for path in sorted(Path(directory).glob(f"{PREFIX}*{SUFFIX}")):
        name = path.name[len(PREFIX):-len(SUFFIX)]
        if _NAME.match(name):
            names.append(name)
    return names


def session_config(name: str, secret: str, connect: list[str], files: Path) -> dict[str, Any]:
    """rmw_zenoh's session configuration for peer `name`: a zenoh client of the hub (everything it
    sends crosses the hub's rules), over TLS with mutual authentication, logging in as its user;
    `files`: the folder where its certificate, key and the authority's certificate lie on the ROS 2
    machine. It replaces rmw_zenoh's default configuration whole, so it keeps what rmw_zenoh needs
    of it."""
    return {
        "mode": "client",
        "connect": {"endpoints": list(connect)},
        "listen": {"endpoints": []},
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
        # as rmw_zenoh's own default session configuration has them: a transient-local publisher
        # (an advanced publisher with a cache) needs timestamps, and its subscribers' history
        # queries a long timeout
        "timestamping": {"enabled": True, "drop_future_timestamp": False},
        "queries_default_timeout": 60000,
        "transport": {
            "link": {"tls": {
                "root_ca_certificate": str(files / AUTHORITY_CERTIFICATE),
                "connect_certificate": str(files / f"{peer_user(name)}.pem"),
                "connect_private_key": str(files / f"{peer_user(name)}.key"),
                "enable_mtls": True,
                # the hub is reached by address; the authority, not the name, says who it is
                "verify_name_on_connect": False,
            }},
            "auth": {"usrpwd": {"user": peer_user(name), "password": secret}},
        },
    }


def make_peer(directory: str | Path, name: str, connect: list[str], files: str | Path | None = None,
              days: int = 825, force: bool = False) -> Path:
    """Sign ROS 2 peer `name`'s certificate (ros2-NAME.pem, .key) and write its session
    configuration (ros2-NAME.json5, readable by its owner only: it holds the password)."""
    if not _NAME.match(name or ""):
        raise CertificateError(f"ROS 2 peer name {name!r}: use letters, digits, '_' or '-' (at most 57)")
    bad = [e for e in connect if not e.startswith(("tls/", "quic/"))]
    if not connect or bad:
        raise CertificateError(f"--connect: the hub's tls/ endpoint (e.g. tls/10.0.0.1:7447), not "
                               f"{', '.join(bad) or 'nothing'}: a ROS 2 peer reaches the hub over TLS only")
    directory = Path(directory)
    secret = password(directory, name)
    issue_host(directory, peer_user(name), days=days, force=force)
    where = Path(files).expanduser() if files else directory.resolve()
    path = config_path(directory, name)
    text = ("// rmw_zenoh's session configuration for ROS 2 peer " + repr(name) + ", written by 'iotad certs ros2':\n"
            "// export ZENOH_SESSION_CONFIG_URI=<this file> (docs/ros2.md). It holds the peer's password.\n"
            + json.dumps(session_config(name, secret, connect, where), indent=2) + "\n")
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "w") as handle:
        handle.write(text)
    os.chmod(path, 0o600)
    return path


def grants_for(system: Any, directory: str | Path | None) -> list[Any]:
    """The hub's grants for the ROS 2 peers in `directory`, from the system's `[[ros2]]` tables;
    none without tables (a peer would have nothing to do)."""
    from iotad.launcher.access.access_policy import Grant
    from iotad.launcher.system.ros2_tables import mappings_of
    from iotad.ros2.mapping import Mapping
    from iotad.ros2.rights import peer_rights

    names = peers(directory)
    mappings = [Mapping.from_plain(plain) for plain in mappings_of(system)]
    if not names or not mappings:
        return []
    rights = peer_rights(mappings)
    return [Grant(peer_user(name), "ROS 2 peer", publish=list(rights.publish), subscribe=list(rights.subscribe),
                  ask=list(rights.ask), tokens=list(rights.tokens), watch=list(rights.watch)) for name in names]


def peer_grants(system: Any, directory: str | Path | None) -> tuple[list[Any], dict[str, str]]:
    """The hub's users for the ROS 2 peers in `directory`: their grants and passwords (derived
    from the authority's key there; CertificateError, one line, without it)."""
    grants = grants_for(system, directory)
    return grants, {grant.user: password(directory, grant.user[len(PREFIX):]) for grant in grants}
