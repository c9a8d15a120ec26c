"""Restart notices: an IOTA learns that a node it waits on has restarted, as an input event.

A restarted node starts from its initial state: whatever it was doing for others (a request it
was scheduling, a motion program it was running, a joint command it was holding) is gone, and
whoever waits for its answer would wait forever. So the restart must be visible to them, and in
the only way an IOTA sees anything: an input. An IOTA that waits on its peers declares

    peer_restart = Input()                       # Python API; ESPRIT: peer_restart()/0

(or an enum of its own channel names, to learn through which of its channels the restarted peer
was bound) and its node host feeds it one event each time a node bound to one of its inputs (a
source it waits on) or one of its outputs (a reader that may have lost what it was sent: the MDL
interpreter lost the program the scheduler sent it) comes back after it went away:
its liveliness token `iota/<system>/<peer>/@alive` vanished (killed, crashed, stopped by the
launcher as frozen) and reappeared with another process behind it (a host cut off past zenoh's
lease loses its tokens too, and brings them back with the same processes: no notice). A node
host declares the token after its subscribers and its `@spec` queryable, so a request sent on
the notice reaches the new process, and the watch can ask it who it is. The notice arrives as an input from the
node's own key `iota/<system>/<node>/peer_restart`, so it is in the trace and the recording, and
replay feeds it back like any input; `iotad pub` can send one by hand.

What the IOTA makes of it is its own business (docs/failures.md): the Figure 2 requester takes a
restart of the scheduler while it waits as an ABORT and goes on with its next request; the
resume scheduler sends its master's program again when the MDL interpreter restarts.

`PeerWatch` is the piece that does the watching; it needs only a zenoh session, so a Python tool
that is no IOTA can use it too.
"""
from __future__ import annotations

import threading
from typing import Any, Callable, Iterable

from iotad.node_host import wire

PEER_RESTART = "peer_restart"  # the reserved input channel a node host feeds


def peers_of(system: str, own_path: str, inputs: dict[str, list[str]],
             readers: dict[str, list[str]] | None = None) -> dict[str, list[str]]:
    """peer node path -> the names of this node's channels bound to that peer: its inputs bound
    to the peer's outputs (a node config's `inputs`: "chan" or "chan/k" -> keys of the bound
    outputs), then its outputs the peer reads (`readers`: "chan" or "chan/k" -> node paths)."""
    peers: dict[str, list[str]] = {}

    def add(peer: str, label: str) -> None:
        if peer == own_path or peer.startswith("@"):
            return
        names = peers.setdefault(peer, [])
        name = label.split("/", 1)[0]
        if name not in names:
            names.append(name)

    for label, keys in inputs.items():
        for key in keys:
            parsed = wire.parse_key(key)
            if parsed is not None and parsed[0] == system:
                add(parsed[1], label)
    for label, nodes in (readers or {}).items():
        for node in nodes:
            add(node, label)
    return peers


def notice_values(channel_type: Any, channels: Iterable[str]) -> list[Any]:
    """The values of the notices for a peer bound to `channels` (this node's channel names):
    one `None` for a channel without a value; for an enum, each of those names that is a member
    of it (none: the IOTA does not care about that peer)."""
    if channel_type is None:
        return [None]
    members = getattr(channel_type, "members", None)
    if members is None:
        raise ValueError(f"input {PEER_RESTART!r} must carry no value or an enum of channel names, "
                         f"not {channel_type}")
    return [name for name in channels if name in members]


class PeerWatch:
    """Calls `on_restart(peer_path)` each time the liveliness token of one of `peers` (node paths
    of `system`) reappears after it vanished, and the process behind it is another one. A token
    already there when the watch starts, or that first appears later, is a start, not a restart.

    A token also vanishes when its host is cut off for longer than zenoh's lease (10 s), and comes
    back with the links, its process untouched: no restart, and a notice would make an IOTA give
    up what it asked of it (vision asked the scheduler again for a goal 23 s old, out of reach).
    So the watch asks each peer who it is (its `@spec` answer's pid and start time) when its
    token appears, and again when it comes back: the same process is a `rejoin` (counted, no
    notice); another one, or no answer within `ask_timeout`, is a restart. The asking is done on
    a thread of the watch's own, never on zenoh's."""

    def __init__(self, session: Any, system: str, peers: Iterable[str], on_restart: Callable[[str], None],
                 ask_timeout: float = 2.0):
        self.session, self.system, self.peers = session, system, set(peers)
        self._on_restart = on_restart
        self.ask_timeout = ask_timeout
        self._lock = threading.Lock()
        self._present: set[str] = set()
        self._lost: set[str] = set()
        self._process: dict[str, tuple | None] = {}  # the (pid, start) behind each peer's token
        self.restarts: dict[str, int] = {}
        self.rejoins: dict[str, int] = {}
        self._closed = threading.Event()
        self.subscriber = session.liveliness().declare_subscriber(
            wire.every_node(system, wire.ALIVE), self._on_sample, history=True)

    def _on_sample(self, sample: Any) -> None:
        import zenoh
        path = wire.node_path(sample.key_expr, self.system, wire.ALIVE)
        if path not in self.peers:
            return
        with self._lock:
            if sample.kind == zenoh.SampleKind.DELETE:
                if path in self._present:
                    self._present.discard(path)
                    self._lost.add(path)
                return
            if path in self._present:
                return  # the same token seen twice (history and live)
            self._present.add(path)
            back = path in self._lost
            self._lost.discard(path)
        threading.Thread(target=self._identify, args=(path, back), name=f"peer {path}", daemon=True).start()

    def _identify(self, path: str, back: bool) -> None:
        process = self.process_of(path)
        with self._lock:
            before = self._process.get(path)
            self._process[path] = process
            if not back or self._closed.is_set():
                return
            rejoined = process is not None and process == before
            counts = self.rejoins if rejoined else self.restarts
            counts[path] = counts.get(path, 0) + 1
        if not rejoined:
            self._on_restart(path)

    def process_of(self, path: str) -> tuple | None:
        """(pid, start time) of the process that answers for `path` now, None without an answer."""
        try:
            for reply in self.session.get(wire.node_key(self.system, path, wire.SPEC), timeout=self.ask_timeout):
                ok = getattr(reply, "ok", None)
                if ok is None:
                    continue
                described = wire.decode(ok.payload.to_bytes())
                if isinstance(described, dict) and described.get("pid") is not None:
                    return described.get("pid"), described.get("started")
        except Exception:  # noqa: BLE001 - a closed session, a refused query: who it is stays unknown
            return None
        return None

    def undeclare(self) -> None:
        self._closed.set()
        self.subscriber.undeclare()


def told_of(system: str, path: str, inputs: dict[str, list[str]], readers: dict[str, list[str]] | None,
            channel_type: Any) -> dict[str, list[Any]]:
    """peer node path -> the values of the notices its restart makes (`notice_values`), for the
    peers whose restarts the node is told of at all: what its host watches, and whose `@spec`
    the access policy lets it ask (to tell a restart from a return after a cut)."""
    notices = {peer: notice_values(channel_type, channels)
               for peer, channels in peers_of(system, path, inputs, readers).items()}
    return {peer: values for peer, values in notices.items() if values}


def watch_for_host(session: Any, config: Any, channel_type: Any, post: Callable[[Any], None]) -> PeerWatch | None:
    """The node host's watch: for a root IOTA with a `peer_restart` input, post a notice to the
    engine (`post`, never dropped by a full input queue) for each restart of a node bound to
    one of its inputs or outputs. None when the IOTA has no such input or no peers it is told of."""
    from iotad.node_host.host_clock import RawInput

    notices = told_of(config.system, config.path, config.inputs, config.readers, channel_type)
    if not notices:
        return None
    key = wire.channel_key(config.system, config.path, PEER_RESTART)
    payloads = {peer: [wire.encode(value) for value in values] for peer, values in notices.items()}

    def restarted(peer: str) -> None:
        for payload in payloads[peer]:
            post(RawInput(PEER_RESTART, None, payload, None, key))

    return PeerWatch(session, config.system, payloads, restarted)
