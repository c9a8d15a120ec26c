"""The secret by which a host's agent proves itself to the hub of a run under access control
(docs/hosts.md): `HOST.secret`, written beside the host's certificate by `iotad certs host`.

Why a secret as well as the certificate: zenoh's user-password authentication is asked of every
session that opens with a hub under access control, and a certificate alone would admit any
machine of the authority (a guest, a laptop) as that host. The secret is derived from the
authority's key (HMAC-SHA256 of the host's name), so the hub, which holds `ca.key`, needs no
file per host, and knowing one host's secret tells nothing of another's or of the key."""
from __future__ import annotations

import hashlib
import hmac
import os
from pathlib import Path

from iotad.machine.certificates import AUTHORITY_KEY, CertificateError

SUFFIX = ".secret"


def agent_user(host: str) -> str:
    """The user name of `host`'s agent on the hub."""
    return f"iotad-agent-{host}"


def derive(directory: str | Path, host: str) -> str:
    """`host`'s secret from the authority's key in `directory`, or from `HOST.secret` there when
    the key is kept elsewhere. Raises `CertificateError` (one line) when neither is there."""
    directory = Path(directory)
    try:
        key = (directory / AUTHORITY_KEY).read_bytes()
    except OSError:
        return read(directory, host, f"(nor the authority's key {directory / AUTHORITY_KEY} to derive it)")
    return hmac.new(key, f"iotad agent {host}".encode(), hashlib.sha256).hexdigest()


def read(directory: str | Path, host: str, why: str = "") -> str:
    """The secret an agent of `host` was given (`HOST.secret` in its certificates' folder)."""
    path = Path(directory) / f"{host}{SUFFIX}"
    try:
        text = path.read_text().strip()
    except OSError:
        raise CertificateError(f"no agent secret for host {host!r}: {path} is missing {why}".rstrip() +
                               f"; make it with 'iotad certs secret {host} --dir DIR' where the authority's "
                               "key is, and copy it beside the host's key") from None
    if len(text) < 32:
        raise CertificateError(f"{path}: not an agent secret (too short); make it again with "
                               f"'iotad certs secret {host}'")
    return text


def write(directory: str | Path, host: str) -> Path:
    """Write `HOST.secret` (readable by its owner only) from the authority's key in `directory`."""
    path = Path(directory) / f"{host}{SUFFIX}"
    secret = derive(directory, host)
    descriptor = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(descriptor, "w") as handle:
        handle.write(secret + "\n")
    os.chmod(path, 0o600)
    return path


__all__ = ["SUFFIX", "agent_user", "derive", "read", "write"]
