"""One agent serves run after run, whether a run is under access control or not: zenoh refuses a
session that offers a user and password to a hub that checks none (and the reverse), so the
agent joins each run's hub anew once the last one is gone, with its secret where the hub asks
for one. Loopback, TLS, hubs made by the test."""
from agent_helpers import AgentProcess, hub_session

from iotad.machine import agent_secret, certificates
from iotad.node_host.transport import free_port, open_session


def test_an_agent_joins_an_open_hub_then_one_under_access_control_then_an_open_one(tmp_path):
    authority = tmp_path / "ca"
    certificates.init_authority(authority)
    brain = certificates.issue_host(authority, "brain", ["127.0.0.1"])
    certificates.issue_host(authority, "arm", ["127.0.0.1"])
    agent_secret.write(authority, "arm")
    port = free_port()
    agent = AgentProcess(authority, port)
    try:
        seen = 0
        for guarded in (False, True, False):
            if guarded:
                hub = hub_session(authority, port, {"iotad-agent-arm": agent_secret.derive(authority, "arm")}, tmp_path)
            else:
                hub = open_session([f"tls/127.0.0.1:{port}"], [], credentials=False, tls=brain)
            with hub:
                seen = agent.wait_for("ready at the hub", 40, after=seen)
                assert seen >= 0, agent.lines
                assert agent.lines[seen].endswith("(admitted as iotad-agent-arm)") == guarded, agent.lines
            seen = agent.wait_for("the hub is gone; waiting for the next run", 40, after=seen)
            assert seen >= 0, agent.lines
    finally:
        errors = agent.stop()
    assert "Traceback" not in errors and not [line for line in agent.lines if "not admitted" in line], \
        (agent.lines, errors)
