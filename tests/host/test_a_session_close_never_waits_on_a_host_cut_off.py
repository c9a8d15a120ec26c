"""A session close that zenoh cannot finish (links to a host that is cut off linger 10 s, and zenoh
gives up after 10 s with 'close operation timed out') ends after its patience with one line, and so
does one that fails; a close that works says nothing. How many receive threads a process of a run
over hosts gets: one per zenoh session that may sit on another host, beside zenoh's own two."""
import threading
from types import SimpleNamespace

import zenoh

from iotad.node_host.session_close import close_session
from iotad.node_host.zenoh_runtime import DEFAULT_RX, ENV, remote_sessions, rx_threads, setting, use_for


class Lingering:
    def __init__(self, error: Exception | None = None):
        self.released, self.error = threading.Event(), error

    def close(self) -> None:
        self.released.wait(30)
        if self.error is not None:
            raise self.error


def test_a_close_that_cannot_finish_is_left_to_the_system_in_one_line():
    session = Lingering()
    try:
        problem = close_session(session, patience=0.2)
    finally:
        session.released.set()
    assert problem is not None and problem.startswith("zenoh: ") and "\n" not in problem, problem


def test_a_close_that_fails_says_why_in_one_line():
    session = Lingering(zenoh.ZError("close operation timed out!\nat /root/.cargo/..."))
    session.released.set()
    problem = close_session(session, patience=5)
    assert problem == "zenoh: the session did not close cleanly (close operation timed out!); left to the system"


def test_a_session_that_closes_says_nothing():
    session = Lingering()
    session.released.set()
    assert close_session(session) is None
    assert close_session(None) is None


def system(nodes: dict[str, str], buses: int = 0):
    return SimpleNamespace(nodes={name: SimpleNamespace(host=host) for name, host in nodes.items()}, buses=[0] * buses)


def test_each_process_gets_a_receive_thread_per_session_that_may_sit_on_another_host():
    split = system({"tick": "brain", "near": "brain", "beat": "arm", "far": "arm", "vision": "base"}, buses=1)
    # on brain: arm's 2 nodes and base's 1, each other host's launcher, recorder, agent and a tool, the bus logger
    assert remote_sessions(split, "brain") == 3 + 2 * 4 + 1
    assert rx_threads(remote_sessions(split, "brain")) == DEFAULT_RX + 12
    assert rx_threads(10_000) == 64 and rx_threads(0) == DEFAULT_RX
    env: dict[str, str] = {}
    assert use_for(split, "arm", env) == setting(DEFAULT_RX + 3 + 2 * 4 + 1) == env[ENV]


def test_a_system_on_one_host_or_a_users_own_setting_is_left_alone():
    env: dict[str, str] = {}
    assert use_for(system({"a": None, "b": None}), None, env) is None and env == {}
    assert use_for(system({"a": "arm", "b": "arm"}), "arm", env) is None and env == {}
    mine = {ENV: "(rx: (worker_threads: 3))"}
    assert use_for(system({"a": "brain", "b": "arm"}), "brain", mine) is None
    assert mine == {ENV: "(rx: (worker_threads: 3))"}
