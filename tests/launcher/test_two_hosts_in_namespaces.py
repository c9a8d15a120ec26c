"""Two hosts as two network namespaces joined by a veth pair: the scheduler on host a (which also
holds the hub), the requester on host b, one `iotad run --host` per namespace. Only private
addresses inside namespaces this test creates and removes; no traffic leaves them."""
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from launcher_helpers import ROOT, launcher

EXAMPLES = ROOT / "examples"


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


@pytest.fixture
def two_hosts():
    """Namespaces a and b, veth 10.200.0.1/24 (a) <-> 10.200.0.2/24 (b); removed afterwards."""
    tag = f"{os.getpid() % 100000}"
    ns_a, ns_b = f"iotad-a-{tag}", f"iotad-b-{tag}"
    veth_a, veth_b = f"iva{tag}", f"ivb{tag}"
    made = []
    try:
        for ns in (ns_a, ns_b):
            result = ip("netns", "add", ns)
            if result.returncode != 0:
                pytest.skip(f"cannot create network namespaces here (ip netns add: {result.stderr.strip()}); "
                            "this test needs root or CAP_NET_ADMIN")
            made.append(ns)
        steps = [("link", "add", veth_a, "type", "veth", "peer", "name", veth_b),
                 ("link", "set", veth_a, "netns", ns_a), ("link", "set", veth_b, "netns", ns_b),
                 ("-n", ns_a, "addr", "add", "10.200.0.1/24", "dev", veth_a),
                 ("-n", ns_b, "addr", "add", "10.200.0.2/24", "dev", veth_b),
                 ("-n", ns_a, "link", "set", veth_a, "up"), ("-n", ns_b, "link", "set", veth_b, "up"),
                 ("-n", ns_a, "link", "set", "lo", "up"), ("-n", ns_b, "link", "set", "lo", "up")]
        for step in steps:
            result = ip(*step)
            if result.returncode != 0:
                pytest.skip(f"cannot wire the namespaces (ip {' '.join(step)}: {result.stderr.strip()})")
        yield ns_a, ns_b
    finally:
        for ns in made:
            ip("netns", "del", ns)  # takes its end of the veth pair (and so the pair) with it


SYSTEM = f"""
[system]
name = "twohost"
hub_host = "a"
[system.endpoints]
listen = ["tcp/10.200.0.1:7613"]   # not zenoh's default 7447: once, on a dev machine, nothing reached a hub on 7447 while other ports worked

[hosts.a]
listen = ["tcp/10.200.0.1:0"]
[hosts.b]
listen = ["tcp/10.200.0.2:0"]

[[node]]
name = "scheduler"
host = "a"
python = "{EXAMPLES}/scheduler.py:Scheduler"
params = {{ N = 1, T = 0.5 }}

[[node]]
name = "vision"
host = "b"
python = "{EXAMPLES}/requesters.py:Requester"
params = {{ priority = 1, epoch = 1.0, timeout = 2.0, start = 0.5, pause = 1.2, count = 2 }}
after = ["scheduler"]

[[bind]]
from = "vision.req"
to = "scheduler.req[0]"
[[bind]]
from = "scheduler.ack[0]"
to = "vision.ack"
"""


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
    assert "vision.req" in out_a and "scheduler.ack[0]         -> vision.ack             2 events: COMMIT x2" in out_a, out_a
    assert "2 events: COMMIT x2" in out_b and "scheduler: live (on another host)" in out_b, out_b
    assert "vision: live (on another host)" in out_a, out_a
