"""With two hosts or more besides the hub's under access control, the hub and the hosts' routers
are zenoh routers (`host_access.zenoh_mode`), so that the hub relays from one host's router to
another's: a requester on arm reaches the scheduler on base, and the scheduler's answers reach
the requester. The hub still judges each router's link as its launcher user: what arm's router
publishes on a key that only base's node may publish (the scheduler's answer) reaches no one,
while the same key from base arrives. A system over two hosts, or on one, keeps the peer mode it
always ran in. On loopback, with the run's certificates and credentials."""
import time

import pytest

from agent_helpers import authority_for
from launcher_helpers import free_port, wait_until
from namespaces import split_figure2

from iotad.machine import certificates

from iotad.node_host import wire
from iotad.node_host.credentials import CredentialStore, load
from iotad.node_host.transport import open_session
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.access.access_policy import node_user
from iotad.launcher.access.host_access import launcher_user, zenoh_mode
from iotad.launcher.system.system_file import load_system


@pytest.fixture
def certs(tmp_path):
    return authority_for(tmp_path / "certs", {host: ["127.0.0.1"] for host in ("brain", "arm", "base")})


def system_file(tmp_path, port: int, third: bool):
    path = tmp_path / "system.toml"
    path.write_text(split_figure2("split", "127.0.0.1", port, "brain", "arm", "127.0.0.1", "tls",
                                  third=("base", "127.0.0.1") if third else None))
    return load_system(path)


def test_only_a_hub_between_two_hosts_routers_or_more_is_a_router(tmp_path, certs):
    assert zenoh_mode(system_file(tmp_path, 7447, third=False)) == "peer"
    two = AccessControl(system_file(tmp_path, 7447, third=False), hosts=("arm",), certs=str(certs))
    three = AccessControl(system_file(tmp_path, 7447, third=True), hosts=("arm", "base"), certs=str(certs))
    try:
        assert two.hub_options()["mode"] == "peer" and three.hub_options()["mode"] == "router"
    finally:
        two.close()
        three.close()


def test_the_hub_relays_between_two_hosts_routers_what_each_may_publish_and_nothing_else(tmp_path, certs):
    port = free_port()
    system = system_file(tmp_path, port, third=True)
    hub_endpoint = f"tls/127.0.0.1:{port}"
    hub = AccessControl(system, hosts=("arm", "base"), certs=str(certs))
    received, routers, sessions = [], {}, []
    try:
        sessions.append(open_session([hub_endpoint], [], tls=certificates.host_files(certs, "brain"), **hub.hub_options()))
        heard = {"base": [], "arm": [], "hub": []}
        for host in ("arm", "base"):
            received.append(CredentialStore([], passwords=hub.host_part(host)))  # what its agent writes
            routers[host] = AccessControl(system, given=str(received[-1].file_of(launcher_user(host))))
            endpoint = routers[host].route(host)
            assert routers[host].hub_options()["mode"] == "router"
            sessions.append(open_session([endpoint], [hub_endpoint], tls=certificates.host_files(certs, host),
                                         **routers[host].hub_options()))
        hub_session, arm_router, base_router = sessions
        assert wait_until(lambda: len(list(hub_session.info.routers_zid())) == 2, 20), "the routers never linked"

        def client(host: str, node: str):
            store = routers[host].router.store
            session = open_session([], [routers[host].router.endpoint], mode="client", connect_timeout=3,
                                   credentials=load(store.file_of(node_user(node))))
            sessions.append(session)
            return session

        vision, scheduler = client("arm", "vision"), client("base", "scheduler")
        request, answer = wire.channel_key("split", "vision", "req"), wire.channel_key("split", "scheduler", "ack", 0)
        scheduler.declare_subscriber(request, lambda sample: heard["base"].append(sample.payload.to_bytes()))
        vision.declare_subscriber(answer, lambda sample: heard["arm"].append(sample.payload.to_bytes()))
        hub_session.declare_subscriber(answer, lambda sample: heard["hub"].append(sample.payload.to_bytes()))
        forged, sent = wire.encode("FORGED"), wire.encode("COMMIT")

        def exchanged() -> bool:
            """One request, one answer from base, and one forged answer from arm's router, which as
            arm's launcher user may not publish it: whether base's answers arrived."""
            vision.put(request, wire.encode({"priority": 1}))
            arm_router.put(answer, forged)
            scheduler.put(answer, sent)
            time.sleep(0.05)
            return bool(heard["base"]) and heard["arm"].count(sent) >= 5 and heard["hub"].count(sent) >= 5

        assert wait_until(exchanged, 20), heard
        # the hub dropped each forged answer, while base's on the same key crossed it
        assert forged not in heard["hub"], "the hub took from arm's router what only base's node may publish"
        # every message between arm and base crossed the hub: their routers never linked to each other
        assert list(arm_router.info.routers_zid()) == [hub_session.info.zid()]
        assert list(base_router.info.routers_zid()) == [hub_session.info.zid()]
    finally:
        for session in reversed(sessions):
            session.close()
        for router in routers.values():
            router.close()
        for store in received:
            store.remove()
        hub.close()
