"""Closing a zenoh session without waiting on a host that cannot be reached.

A session with a link to a host that is cut off closes slowly: zenoh closes each such link with
SO_LINGER 10 s (iotad/node_host/zenoh_runtime.py says why), and gives up after its own 10 s with
`ZError: close operation timed out`. A launcher stopped while its host was cut off ended on that
error, exit 2, after its nodes had been killed for not stopping in time, and printed no summary.
Nothing is left to send on such a link, so the close runs on a thread of its own here, and the
process goes on (and ends) after `patience` seconds whatever zenoh still waits for; the kernel
drops the socket when the process exits."""
from __future__ import annotations

import threading

PATIENCE = 1.5  # s: a close on live links takes milliseconds; a node has 3 s to stop after SIGINT


def close_session(session, patience: float = PATIENCE) -> str | None:
    """Close `session`; None when it closed, else one line saying why it did not (in time)."""
    if session is None:
        return None
    outcome: dict = {}

    def close() -> None:
        try:
            session.close()
        except Exception as exc:  # noqa: BLE001 - zenoh's ZError, said in one line
            outcome["error"] = str(exc).splitlines()[0] if str(exc) else type(exc).__name__

    closer = threading.Thread(target=close, name="zenoh-close", daemon=True)
    closer.start()
    closer.join(patience)
    if closer.is_alive():
        return (f"zenoh: the session did not close within {patience:g} s (a link to a host that cannot be "
                "reached); left to the system")
    if "error" in outcome:
        return f"zenoh: the session did not close cleanly ({outcome['error']}); left to the system"
    return None
