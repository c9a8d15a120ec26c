"""The wire between the hub and the agents of a system spread over hosts, spelled in one place:
the `iota/@agent/<host>` and `iota/@code/<sha256>` keys ('@' chunks: no system's `iota/<system>/**`
matches them), the digest that names a system file's text in an order, and the zenoh user names
of a host's launcher and of the hub's fleet session (an agent's own is `agent_secret.agent_user`)."""
from __future__ import annotations

import hashlib

AGENT_PREFIX = "iota/@agent"
CODE_PREFIX = "iota/@code"
FLEET_USER = "iotad-fleet"  # the hub launcher's own client session that talks to the agents


def agent_key(name: str) -> str:
    """Where host `name`'s agent is: its liveliness token; `/run`, `/stop`, `/lines`, `/log`, `/exit` below."""
    return f"{AGENT_PREFIX}/{name}"


def code_key(sha256: str) -> str:
    """Where the hub serves the named file whose content hashes to `sha256`."""
    return f"{CODE_PREFIX}/{sha256}"


def digest(text: str) -> str:
    """The sha256 of a system file's text, as an order names it."""
    return hashlib.sha256(text.encode()).hexdigest()


def launcher_user(host: str) -> str:
    """The zenoh user of `host`'s launcher under access control."""
    return f"iotad-launcher-{host}"
