"""The router of a host that is not the hub's (iotad/launcher/access/host_router.py) enforces access
control for its local clients as the hub does: on its private unix socket it admits arm's node
and arm's recorder with the passwords it made for them on arm (the agent receives only the
launcher's), refuses a wrong password and a user of another host, and drops what arm's node may
not publish (another node's output) while the recorder hears what it may. The hub's policy grants arm's launcher user exactly what arm's nodes
may do, and no more."""
import os
import stat
import time
from pathlib import Path

import pytest
import zenoh

from namespaces import split_figure2

from iotad.node_host import wire
from iotad.node_host.credentials import Credentials, CredentialStore, GivenCredentials, load
from iotad.node_host.transport import open_session
from iotad.launcher.access.access_policy import RECORDER_USER, derive, node_user
from iotad.launcher.access.host_access import host_users, launcher_grant, launcher_user
from iotad.launcher.access.host_router import HostRouter
from iotad.launcher.system.system_file import load_system


@pytest.fixture
def system(tmp_path):
    path = tmp_path / "split.toml"
    path.write_text(split_figure2("split", "127.0.0.1", 7633, "brain", "arm", "127.0.0.2", "tls"))
    return load_system(path)


def test_the_host_router_checks_its_clients_like_the_hub(system):
    received = CredentialStore(host_users(system, "arm"))  # what arm's agent wrote for the run
    assert host_users(system, "arm") == [launcher_user("arm")]
    given = GivenCredentials(received.folder)
    router = HostRouter(system, "arm", load(given.file_of(launcher_user("arm"))))
    sessions = []
    try:
        socket_dir = Path(router.endpoint.partition("/")[2]).parent
        assert stat.S_IMODE(os.stat(socket_dir).st_mode) == 0o700
        sessions.append(open_session([router.endpoint], [], **router.session_options()))

        def client(credentials):
            session = open_session([], [router.endpoint], mode="client", connect_timeout=2, credentials=credentials)
            sessions.append(session)
            return session

        recorder = client(load(router.store.file_of(RECORDER_USER)))
        heard = []
        recorder.declare_subscriber("iota/split/**", lambda sample: heard.append(str(sample.key_expr)))
        vision = client(load(router.store.file_of(node_user("vision"))))
        time.sleep(0.5)
        own, other = wire.channel_key("split", "vision", "req"), wire.channel_key("split", "scheduler", "ack", 0)
        deadline = time.monotonic() + 10
        while own not in heard and time.monotonic() < deadline:
            vision.put(other, wire.encode("FORGED"))
            vision.put(own, wire.encode({"priority": 1}))
            time.sleep(0.1)
        assert own in heard and other not in heard, heard
        # arm's router knows arm's users only: a guessed password, or the scheduler's user (a node of brain)
        with pytest.raises(zenoh.ZError):
            client(Credentials(node_user("vision"), "guessed"))
        with pytest.raises(zenoh.ZError):
            client(Credentials(node_user("scheduler"), "anything"))
    finally:
        for session in reversed(sessions):
            session.close()
        router.close()
        received.remove()
    assert not Path(router.store.folder).exists()


def test_the_hubs_launcher_user_may_do_what_its_hosts_nodes_may_and_no_more(system):
    grant = launcher_grant(system, "arm")
    vision = derive(system).grant(node_user("vision"))
    scheduler = derive(system).grant(node_user("scheduler"))
    for part in ("publish", "subscribe", "serve", "tokens", "watch"):
        assert set(getattr(vision, part)) <= set(getattr(grant, part)), part
    # brain's node's outputs are not arm's to publish, and no key outside the system is granted
    assert not set(scheduler.publish) - set(vision.publish) & set(grant.publish)
    assert all(key.startswith("iota/split/") for key in grant.publish), grant.publish
