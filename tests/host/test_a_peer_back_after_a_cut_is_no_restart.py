"""A peer's liveliness token also vanishes when its host is cut off past zenoh's lease, and comes
back with the links, its process untouched: the watch asks the process behind the token who it is
(its `@spec` answer's pid and start) and tells the IOTA of a restart only when it is another one,
or when nobody answers. Two zenoh sessions on loopback: one plays the peer (token and `@spec`),
the other watches it."""
import threading

from iotad.launcher.access.access_policy import derive, node_user
from iotad.launcher.system.system_file import load_system
from iotad.node_host import transport, wire
from iotad.node_host.peer_restart import PeerWatch

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SYSTEM, PEER = "robot", "scheduler"
WAIT = 10.0  # s: the most any step may take before the test fails (each waits on an event)


class Peer:
    """The peer node as its watchers see it: a liveliness token and a `@spec` answer."""

    def __init__(self, session, pid: int, started: float):
        self.session, self.described = session, {"pid": pid, "started": started, "path": PEER}
        key = wire.node_key(SYSTEM, PEER, wire.SPEC)
        self.queryable = session.declare_queryable(key, lambda query: query.reply(key, wire.encode(self.described)))
        self.token = None

    def appear(self):
        self.token = self.session.liveliness().declare_token(wire.node_key(SYSTEM, PEER, wire.ALIVE))

    def vanish(self):
        self.token.undeclare()


def test_a_token_back_with_the_same_process_is_a_rejoin_and_another_process_is_a_restart():
    endpoint = f"tcp/127.0.0.1:{transport.free_port()}"
    notices: list[str] = []
    told = threading.Event()

    def restarted(path):
        notices.append(path)
        told.set()

    with transport.open_session([endpoint], [], credentials=False) as peer_side, \
            transport.open_session([], [endpoint], mode="client", connect_timeout=5, credentials=False) as watcher:
        peer = Peer(peer_side, pid=4242, started=1000.0)
        peer.appear()
        watch = PeerWatch(watcher, SYSTEM, [PEER], restarted)
        try:
            assert _until(lambda: watch._process.get(PEER) == (4242, 1000.0)), watch._process
            # its host cut off past the lease, then back: the same process answers
            peer.vanish()
            assert _until(lambda: PEER not in watch._present)
            peer.appear()
            assert _until(lambda: watch.rejoins.get(PEER) == 1), (watch.rejoins, watch.restarts)
            assert notices == [] and watch.restarts == {}
            # killed and started again: another process behind the token
            peer.vanish()
            assert _until(lambda: PEER not in watch._present)
            peer.described = {"pid": 4343, "started": 1010.0, "path": PEER}
            peer.appear()
            assert told.wait(WAIT) and notices == [PEER] and watch.restarts == {PEER: 1}
            # a token back whose process does not answer is taken for a restart (it may be one)
            told.clear()
            peer.vanish()
            assert _until(lambda: PEER not in watch._present)
            peer.queryable.undeclare()
            watch.ask_timeout = 0.5
            peer.appear()
            assert told.wait(WAIT) and notices == [PEER, PEER] and watch.restarts == {PEER: 2}
        finally:
            watch.undeclare()


def test_a_node_told_of_restarts_may_ask_its_peers_who_they_are_and_no_other_node():
    policy = derive(load_system(ROOT / "examples" / "conveyor.toml", check=True))
    # vision and manipulation are told of the scheduler's restarts, the scheduler of the interpreter's
    assert policy.grant(node_user("vision")).ask == ["iota/conveyor/scheduler/@spec"]
    assert policy.grant(node_user("manipulation")).ask == ["iota/conveyor/scheduler/@spec"]
    assert "iota/conveyor/interpreter/@spec" in policy.grant(node_user("scheduler")).ask
    assert policy.grant(node_user("planning")).ask == []  # no peer_restart input: it asks nothing


def _until(condition) -> bool:
    """Whether `condition()` holds within WAIT, tried as zenoh's threads deliver (no fixed sleep)."""
    done = threading.Event()
    for _ in range(int(WAIT / 0.01)):
        if condition():
            return True
        done.wait(0.01)
    return condition()
