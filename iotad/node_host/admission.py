"""Why a hub did not admit a session, in one line. zenoh says only "Unable to connect" whether
nothing listens, the hub refused this host's certificate, or it refused its credentials; this
asks the network itself: a TCP connection (does anything listen?), then for a `tls/` endpoint a
TLS handshake with the same certificates (does the hub accept ours, do we accept its?). Whatever
is left, when both pass, is the hub's user-password check (docs/hosts.md, "Access control")."""
from __future__ import annotations

import socket
import ssl
from dataclasses import dataclass

from iotad.machine.certificates import TlsFiles


@dataclass(frozen=True)
class Refusal:
    listening: bool  # something answers there: a refusal, not a hub that is not up yet
    reason: str      # one line for the user ("" while nothing listens)


def _split(endpoint: str) -> tuple[str, str, str]:
    protocol, _, address = endpoint.partition("/")
    host, _, port = address.split("?", 1)[0].rpartition(":")
    return protocol, host.strip("[]"), port


def listening(endpoint: str, timeout: float = 1.0) -> bool:
    """Whether anything accepts a TCP connection at a tcp/ or tls/ `endpoint` (True for others:
    only zenoh can tell)."""
    protocol, host, port = _split(endpoint)
    if protocol not in ("tcp", "tls") or not port.isdigit():
        return True
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
        return True
    except OSError:
        return False


def diagnose(endpoint: str, tls: TlsFiles | None, user: str | None, timeout: float = 2.0) -> Refusal:
    """What stood between this process and the hub at `endpoint`, where zenoh did not open a
    session: `tls` the certificates it showed, `user` the user it authenticated as (None: none)."""
    protocol, host, port = _split(endpoint)
    if protocol not in ("tcp", "tls") or not port.isdigit():
        return Refusal(True, f"the hub at {endpoint} did not admit this session")
    try:
        raw = socket.create_connection((host, int(port)), timeout=timeout)
    except OSError as exc:
        return Refusal(False, f"nothing answers at {endpoint} ({exc.strerror or exc}): no run holds the hub yet")
    with raw:
        if protocol == "tls":
            problem = _tls_problem(raw, tls, endpoint, timeout)
            if problem:
                return Refusal(True, problem)
    if user is None:
        return Refusal(True, f"the hub at {endpoint} runs under access control and this process has no "
                             "credentials (an agent needs its HOST.secret beside its certificate: docs/hosts.md)")
    return Refusal(True, f"the hub at {endpoint} refused the credentials of user {user!r}: they are not this "
                         "run's (an agent's HOST.secret from another authority, or a stale credentials file)")


def _tls_problem(raw: socket.socket, tls: TlsFiles | None, endpoint: str, timeout: float) -> str:
    if tls is None:
        return f"the hub at {endpoint} is a TLS endpoint and this process has no certificate (--certs DIR)"
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.check_hostname = False  # as zenoh's verify_name_on_connect = false: the authority proves who
    try:
        context.load_verify_locations(str(tls.authority))
        context.load_cert_chain(str(tls.certificate), str(tls.key))
    except (OSError, ssl.SSLError) as exc:
        return f"this host's certificate files cannot be read: {exc}"
    try:
        with context.wrap_socket(raw, do_handshake_on_connect=False) as secured:
            secured.settimeout(timeout)
            secured.do_handshake()
            secured.settimeout(min(timeout, 1.0))
            try:
                # TLS 1.3: a server that rejects the client's certificate says so after the
                # handshake, in an alert that the first read raises; a hub that accepts it waits
                # for zenoh's own first message and sends nothing
                if not secured.recv(1):
                    raise ConnectionResetError("closed")
            except (TimeoutError, socket.timeout):
                return ""
    except ssl.SSLCertVerificationError:
        return (f"the hub at {endpoint} shows a certificate that this host's authority ({tls.authority}) did not "
                "sign: this host's certificates are not the system's")
    except (ssl.SSLError, ConnectionError, TimeoutError, socket.timeout, OSError):
        return (f"the hub at {endpoint} refused this host's certificate ({tls.certificate}): it is not of the "
                "system's authority")
    return ""


__all__ = ["Refusal", "diagnose", "listening"]
