"""A partition longer than zenoh's lease takes a host's agent away from the hub (its liveliness
token goes) and gives it back when the network heals, while that host's nodes ran on. The hub's
run says both, and the host's part that then ends as asked is not a failure of the run; a host
that never comes back is. (The agent's token is played here as the samples zenoh delivers.)"""
from types import SimpleNamespace

import zenoh

from iotad.launcher.agent import agent_key
from iotad.launcher.fleet import Fleet


def token(host: str, present: bool):
    kind = zenoh.SampleKind.PUT if present else zenoh.SampleKind.DELETE
    return SimpleNamespace(key_expr=agent_key(host), kind=kind)


def fleet(tmp_path, said):
    path = tmp_path / "split.toml"
    path.write_text("[system]\nname = 'split'\n")
    hosts = Fleet(path, ["arm", "base"], ["tcp/127.0.0.1:7447"], [], say=said.append)
    hosts._started = {"arm", "base"}
    return hosts


def test_a_host_back_after_a_partition_is_said_and_ends_as_any_other(tmp_path):
    said = []
    hosts = fleet(tmp_path, said)
    for sample in (token("arm", True), token("base", True), token("arm", False), token("base", False),
                   token("arm", True)):
        hosts._on_agent(sample)
    assert said == ["host arm LOST: its agent is gone (network or machine); its nodes are down until it comes back",
                    "host base LOST: its agent is gone (network or machine); its nodes are down until it comes back",
                    "host arm back: its agent answers again (its nodes ran on while it was away)"]
    hosts._asked_to_stop.add("arm")
    hosts.exits["arm"] = 130
    assert hosts.failures() == ["base: lost"]
    assert hosts.outcome("arm") == "exit 130 (stopped by this run); it was LOST for a while and came back"
    assert hosts.outcome("base") == "LOST (its agent disappeared)"
