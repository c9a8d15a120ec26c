"""A node of an open run over hosts (iotad/launcher/access/open_hosts.py) sends what it publishes with
BLOCK to its own host's sessions as it published it, and to every other session with DROP and
batched: on loopback, one session with a node's settings and its three publishers, and two peers,
one named among its host's sessions and one not; each peer sees the congestion control, priority
and express flag each put arrived with (zenoh keeps them in the sample).

Also: the settings name each node's zenoh id, new at each restart, and the launcher builds them only
for an open run whose nodes sit on two hosts or more."""
import time

import zenoh

from launcher_helpers import IOTAS, free_port, wait_until
from namespaces import hosts_header

from iotad.launcher.access.open_hosts import OpenHosts, session_id, settings
from iotad.launcher.system.system_file import load_system
from iotad.node_host.transport import open_session


# a node's three publishers (iotad/node_host/node_host.py): (key, options)
PUBLISHERS = {"out": {"express": True, "congestion_control": zenoh.CongestionControl.BLOCK},
              "@trace": {"congestion_control": zenoh.CongestionControl.BLOCK, "priority": zenoh.Priority.DATA_LOW},
              "@heartbeat": {}}


def test_a_put_leaves_as_sent_toward_its_own_host_and_with_drop_batched_toward_another():
    port = free_port()
    here, there = session_id("secret", "near", 0), session_id("secret", "far", 0)
    node = settings(session_id("secret", "tick", 0), [here])
    seen: dict[tuple[str, str], set] = {}

    def taker(name):
        def take(sample):
            key = str(sample.key_expr).rsplit("/", 1)[-1]
            seen.setdefault((name, key), set()).add((str(sample.congestion_control).split(".")[-1],
                                                      str(sample.priority).split(".")[-1], sample.express))
        return take

    with open_session([f"tcp/127.0.0.1:{port}"], [], extra=node, credentials=False) as tick, \
            open_session([f"tcp/127.0.0.1:{free_port()}"], [f"tcp/127.0.0.1:{port}"], extra={"id": here},
                         credentials=False) as near, \
            open_session([f"tcp/127.0.0.1:{free_port()}"], [f"tcp/127.0.0.1:{port}"], extra={"id": there},
                         credentials=False) as far:
        assert str(tick.info.zid()) == node["id"]
        for name, session in (("here", near), ("there", far)):
            for key in PUBLISHERS:
                session.declare_subscriber(f"t/tick/{key}", taker(name))
        publishers = [tick.declare_publisher(f"t/tick/{key}", **options) for key, options in PUBLISHERS.items()]

        def everyone_heard():  # until both peers have declared their subscriptions to tick
            for publisher in publishers:
                publisher.put(b"x")
            time.sleep(0.05)
            return len(seen) == 2 * len(PUBLISHERS)

        assert wait_until(everyone_heard, 10), seen
    # toward its own host's session: as sent
    assert seen[("here", "out")] == {("BLOCK", "DATA", True)}, seen
    assert seen[("here", "@trace")] == {("BLOCK", "DATA_LOW", False)}, seen
    assert seen[("here", "@heartbeat")] == {("DROP", "DATA", False)}, seen
    # toward another host's: DROP, batched (the output under a priority that marks it as one)
    assert seen[("there", "out")] == {("DROP", "DATA_HIGH", False)}, seen
    assert seen[("there", "@trace")] == {("DROP", "DATA_LOW", False)}, seen
    assert seen[("there", "@heartbeat")] == {("DROP", "DATA", False)}, seen


def test_each_start_of_a_node_has_an_id_of_its_own_known_to_its_hosts_other_nodes():
    hosts = OpenHosts({"tick": 2, "near": 0}, launcher="abc123")
    ids = {session_id(hosts.secret, "tick", k) for k in range(3)}
    assert len(ids) == 3 and ids <= set(hosts.local) and "abc123" in hosts.local
    first, again = hosts.node_settings("tick", 0), hosts.node_settings("tick", 1)
    zids = {z for item in first["qos/network"] for z in item.get("zids", [])}
    assert first["id"] != again["id"] and first["id"] not in zids and again["id"] in zids
    assert OpenHosts({"tick": 0}, "abc").secret != hosts.secret  # another run's ids are other ids
    assert all(len(i) <= 32 and not i.startswith("0") and int(i, 16) for i in hosts.local)


def test_only_an_open_run_over_two_hosts_or_more_gets_them(tmp_path):
    def system(hosts):
        text = hosts_header("s", "127.0.0.1", 7447, "brain", "arm", "127.0.0.2")
        for k, host in enumerate(hosts):
            text += f'\n[[node]]\nname = "n{k}"\nhost = "{host}"\npython = "{IOTAS}:Pulse"\n'
        path = tmp_path / "s.toml"
        path.write_text(text)
        return load_system(path)

    two = system(["brain", "arm"])
    assert OpenHosts.applies(two, "arm", secured=False)
    assert not OpenHosts.applies(two, "arm", secured=True)   # the routers forward with DROP there
    assert not OpenHosts.applies(two, None, secured=False)   # --local: one machine
    assert not OpenHosts.applies(system(["brain", "brain"]), "brain", secured=False)
