"""Two hosts as two network namespaces joined by a veth pair: the scheduler on host a (which also
holds the hub), the requester on host b, one `iotad run --host` per namespace. Only private
addresses inside namespaces this test creates and removes; no traffic leaves them."""
import pytest

from launcher_helpers import launcher
from namespaces import hosts, split_figure2


@pytest.fixture
def two_hosts():
    """Namespaces a and b, veth 10.200.1.1/24 (a) <-> 10.200.1.2/24 (b); removed afterwards."""
    with hosts("a", "b", net=200) as net:
        yield net.names["a"], net.names["b"]


# the hub on 7613, not zenoh's default 7447: once, on a dev machine, nothing reached a hub on 7447
# while other ports worked
SYSTEM = split_figure2("twohost", "10.200.1.1", 7613, "a", "b", "10.200.1.2")


def test_nodes_split_across_two_namespaces(two_hosts, tmp_path):
    ns_a, ns_b = two_hosts
    system_file = tmp_path / "twohost.toml"
    system_file.write_text(SYSTEM)
    with launcher(system_file, "--host", "a", "--until", "9", "--no-record", prefix=("ip", "netns", "exec", ns_a)) as a, \
            launcher(system_file, "--host", "b", "--until", "8", prefix=("ip", "netns", "exec", ns_b)) as b:
        code_b, code_a = b.wait(30), a.wait(30)
        out_a, out_b = a.output.read_text(), b.output.read_text()
    assert (code_a, code_b) == (0, 0), out_a + "\n----\n" + out_b
    # Requests crossed from b to a, answers from a to b; each launcher saw the other host's node.
    # The hub's summary is the run's; b's counts its own node's outputs (hub.trace_keys_counted).
    assert "vision.req               -> scheduler.req[0]       2 events" in out_a, out_a
    assert "scheduler.ack[0]         -> vision.ack             2 events: COMMIT x2" in out_a, out_a
    assert "vision.req               -> scheduler.req[0]       2 events" in out_b, out_b
    assert "scheduler.ack" not in out_b and "scheduler: live (on another host)" in out_b, out_b
    assert "vision: live (on another host)" in out_a, out_a
