"""A node of an open run over hosts (iotad/launcher/access/open_hosts.py) sends what it publishes with
BLOCK to its own host's sessions with BLOCK, and to every other session with DROP: on loopback, one
session with a node's settings and two peers, one named among its host's sessions and one not; each
peer sees the congestion control the put arrived with (zenoh keeps it in the sample).

Also: the settings name each node's zenoh id, new at each restart, and the launcher builds them only
for an open run whose nodes sit on two hosts or more."""
import time

import zenoh

from launcher_helpers import IOTAS, free_port, wait_until
from namespaces import hosts_header

from iotad.launcher.access.open_hosts import OpenHosts, session_id, settings
from iotad.launcher.system.system_file import load_system
from iotad.node_host.transport import open_session


def test_a_put_leaves_with_block_toward_its_own_host_and_with_drop_toward_another():
    port = free_port()
    here, there = session_id("secret", "near", 0), session_id("secret", "far", 0)
    node = settings(session_id("secret", "tick", 0), [here])
    seen: dict[str, list[str]] = {"here": [], "there": []}
    with open_session([f"tcp/127.0.0.1:{port}"], [], extra=node, credentials=False) as tick, \
            open_session([f"tcp/127.0.0.1:{free_port()}"], [f"tcp/127.0.0.1:{port}"], extra={"id": here},
                         credentials=False) as near, \
            open_session([f"tcp/127.0.0.1:{free_port()}"], [f"tcp/127.0.0.1:{port}"], extra={"id": there},
                         credentials=False) as far:
        assert str(tick.info.zid()) == node["id"]
        for name, session in (("here", near), ("there", far)):
            session.declare_subscriber("t/out", lambda sample, name=name: seen[name].append(str(sample.congestion_control)))
        publisher = tick.declare_publisher("t/out", congestion_control=zenoh.CongestionControl.BLOCK)
        # until both peers have declared their subscription to tick
        assert wait_until(lambda: (publisher.put(b"x"), time.sleep(0.05), seen["here"] and seen["there"])[-1], 10)
    assert set(seen["here"]) == {"CongestionControl.BLOCK"}, seen
    assert set(seen["there"]) == {"CongestionControl.DROP"}, seen


def test_each_start_of_a_node_has_an_id_of_its_own_known_to_its_hosts_other_nodes():
    hosts = OpenHosts({"tick": 2, "near": 0}, launcher="abc123")
    ids = {session_id(hosts.secret, "tick", k) for k in range(3)}
    assert len(ids) == 3 and ids <= set(hosts.local) and "abc123" in hosts.local
    first, again = hosts.node_settings("tick", 0), hosts.node_settings("tick", 1)
    assert first["id"] != again["id"] and first["id"] not in first["qos/network"][1]["zids"]
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
