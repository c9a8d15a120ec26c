"""Under access control the hub admits only who logs in to it: the hub host's nodes, its recorder,
tools and fleet session, and each other host's launcher and agent. Another host's nodes log in to
their host's router (iotad/launcher/access/host_router.py), which makes their passwords on that host:
the hub's `dictionary.txt`, its rules and its credentials folder name none of them, the agent is
sent its launcher's password alone, and a session that shows the hub a node's real password from
another host's router (with a certificate of the system's authority) is refused, while the same
password opens a session at that host's router. The router gossips nothing, so the hub hands no
router's unix socket to another host's router."""
import shutil
import tempfile
import time
from pathlib import Path

import pytest
import zenoh

from agent_helpers import authority_for
from launcher_helpers import free_port, wait_until
from namespaces import split_figure2

from iotad.machine import certificates
from iotad.machine.agent_secret import agent_user
from iotad.node_host.credentials import ENV, CredentialStore, load
from iotad.node_host.transport import open_session
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.access.access_policy import RECORDER_USER, TOOLS_USER, node_user
from iotad.launcher.access.host_access import FLEET_USER, launcher_user
from iotad.launcher.access.host_router import NO_GOSSIP
from iotad.launcher.system.system_file import load_system

# who logs in to the hub of the Figure 2 split: scheduler on brain (the hub's host), vision on arm
HUB_USERS = {node_user("scheduler"), RECORDER_USER, TOOLS_USER, FLEET_USER, launcher_user("arm"), agent_user("arm")}


@pytest.fixture
def certs(tmp_path):
    return authority_for(tmp_path / "certs", {"brain": ["127.0.0.1"], "arm": ["127.0.0.1"], "guest": []})


def split(tmp_path, port: int):
    path = tmp_path / "split.toml"
    path.write_text(split_figure2("split", "127.0.0.1", port, "brain", "arm", "127.0.0.1", "tls"))
    return load_system(path)


def test_the_hubs_dictionary_and_rules_name_only_the_users_that_log_in_to_it(tmp_path, certs):
    hub = AccessControl(split(tmp_path, 7447), hosts=("arm",), certs=str(certs))
    try:
        options = hub.hub_options()
        assert options["credentials"].dictionary == str(hub.store.dictionary)
        checked = {line.split(":", 1)[0] for line in hub.store.dictionary.read_text().splitlines()}
        assert checked == HUB_USERS | {"iotad-hub"}  # the hub's own user, which has no rights
        subjects = {user for subject in options["extra"]["access_control"]["subjects"] for user in subject["usernames"]}
        assert subjects == HUB_USERS
        # no file of the folder names arm's node, not even the tools' (which name keys, not users)
        for path in Path(hub.store.folder).iterdir():
            assert "node-vision" not in path.name and "node-vision" not in path.read_text(), path
        # arm's agent is sent its launcher's password alone, and that user relays vision's rights
        assert list(hub.host_part("arm")) == [launcher_user("arm")]
        assert "iota/split/vision/req" in hub.policy.grant(launcher_user("arm")).publish
    finally:
        hub.close()
    assert not Path(hub.store.folder).exists()


def test_a_node_of_another_host_logs_in_to_its_router_and_is_refused_by_the_hub(tmp_path, certs):
    port = free_port()
    system = split(tmp_path, port)
    hub_endpoint = f"tls/127.0.0.1:{port}"
    hub = AccessControl(system, hosts=("arm",), certs=str(certs))
    received = CredentialStore([], passwords=hub.host_part("arm"))  # what arm's agent writes for the run
    arm = AccessControl(system, given=str(received.file_of(launcher_user("arm"))))
    sessions = []
    try:
        router_endpoint = arm.route("arm")
        # vision's password is made by arm's router, in its own private folder
        vision_file = Path(arm.node_env("vision")[ENV])
        assert vision_file.parent == Path(arm.router.store.folder) and vision_file.name == "node-vision.json"
        assert Path(arm.recorder_env()[ENV]).parent == vision_file.parent
        vision = load(vision_file)
        guest = certificates.host_files(certs, "guest")  # a machine of the system's authority
        sessions.append(open_session([hub_endpoint], [], tls=certificates.host_files(certs, "brain"), **hub.hub_options()))
        router = open_session([router_endpoint], [hub_endpoint], tls=certificates.host_files(certs, "arm"),
                              **arm.hub_options())
        sessions.append(router)
        assert wait_until(lambda: router.info.zid() in sessions[0].info.peers_zid(), 20), "arm's router never linked"

        def opens(endpoint: str, credentials, tls=None) -> bool:
            try:
                with open_session([], [endpoint], mode="client", connect_timeout=3, credentials=credentials, tls=tls):
                    return True
            except zenoh.ZError:
                return False

        assert opens(router_endpoint, vision), "vision's own password opens a session at arm's router"
        assert not opens(hub_endpoint, vision, guest), "the hub admitted arm's node directly"
        assert opens(hub_endpoint, load(hub.tools_file()), guest), "the control: the tools' user opens the hub"
    finally:
        for session in reversed(sessions):
            session.close()
        arm.close()
        received.remove()
        hub.close()
    assert not vision_file.parent.exists()


def test_a_hosts_router_gossips_nothing_so_no_other_router_learns_its_socket(tmp_path, certs):
    """Two hosts' routers linked to one hub: with zenoh's default gossip the hub hands each the
    other's unix socket and they link to each other directly; the routers' setting stops it."""
    received = CredentialStore([], passwords={launcher_user("arm"): "p"})
    router = AccessControl(split(tmp_path, 7447), given=str(received.file_of(launcher_user("arm"))))
    router.route("arm")
    try:
        extra = router.hub_options()["extra"]
        assert all(extra[key] == value for key, value in NO_GOSSIP.items())
    finally:
        router.close()
        received.remove()

    def linked_directly(extra: dict, patience: float) -> bool:
        port = free_port()
        folder = Path(tempfile.mkdtemp(prefix="iotad-gossip-", dir="/tmp"))  # a unix socket's path is short
        sessions = [open_session([f"tcp/127.0.0.1:{port}"], [], credentials=False)]
        try:
            for name in ("arm", "base"):
                socket = folder / f"{name}.sock"
                sessions.append(open_session([f"unixsock-stream/{socket}"], [f"tcp/127.0.0.1:{port}"],
                                             credentials=False, extra=extra))
            hub, arm, base = sessions
            assert wait_until(lambda: len(list(hub.info.peers_zid())) == 2, 20), "the routers never reached the hub"
            return bool(wait_until(lambda: base.info.zid() in arm.info.peers_zid(), patience))
        finally:
            for session in reversed(sessions):
                session.close()
            shutil.rmtree(folder, ignore_errors=True)

    start = time.monotonic()
    assert linked_directly({}, 20), "zenoh's default gossip no longer links the routers: this test proves nothing"
    took = time.monotonic() - start
    # three times as long as the routers took to link with gossip: without it they do not
    assert not linked_directly(NO_GOSSIP, max(3 * took, 3.0))
