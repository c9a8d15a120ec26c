"""A node given a `start_gate` goes live and heartbeats, but its engine starts only once a
liveliness token appears on the gate's key (the launcher's, once every node is live); inputs that
came meanwhile wait for it. A node stopped at the gate ends cleanly, without an engine start."""
from iotad.node_host import wire
from iotad.node_host.node_config import ConfigError, from_dict
from node_harness import ECHO, Node, node_config, wait_for, wait_ready

import pytest

GATE = wire.gate_key("test", None)


def trace(hub, node):
    return hub.values(f"{node.base}/@trace")


def test_the_engine_starts_when_the_gate_opens_and_serves_what_came_before(hub):
    node = Node(node_config(hub, "echo", f"{ECHO}:Echo", start_gate=GATE))
    try:
        hub.subscribe(f"{node.base}/out", f"{node.base}/@trace", f"{node.base}/@heartbeat")
        wait_ready(hub, node)  # heartbeats come while it waits: the launcher sees it alive
        hub.session.put(f"{node.base}/inp", wire.encode(5), attachment=wire.encode_attachment(0))
        # three more heartbeats, all before any firing: the engine has not started
        beats = wait_for(lambda: len(hub.values(f"{node.base}/@heartbeat")) >= 4
                         and hub.values(f"{node.base}/@heartbeat"), what="four heartbeats at the gate")
        assert all(beat["firings"] == 0 for beat in beats)
        assert trace(hub, node) == [] and hub.values(f"{node.base}/out") == []
        waited_until = beats[-1]["t"]

        token = hub.session.liveliness().declare_token(GATE)
        try:
            hub.wait_value(f"{node.base}/out", lambda v: v == 5, what="the echo of the input that waited")
            events = wait_for(lambda: len(trace(hub, node)) >= 3 and trace(hub, node), what="start, input, output")
        finally:
            token.undeclare()
        assert [e["kind"] for e in events[:3]] == ["start", "input", "output"]
        assert events[0]["t"] >= waited_until  # the engine started after the waiting heartbeats
        assert events[1]["t"] >= events[0]["t"]
    finally:
        assert node.stop() == 0


def test_a_gate_already_open_lets_the_engine_start_at_once(hub):
    token = hub.session.liveliness().declare_token(GATE)
    node = Node(node_config(hub, "echo", f"{ECHO}:Echo", start_gate=GATE))
    try:
        hub.subscribe(f"{node.base}/@trace")
        events = wait_for(lambda: trace(hub, node), what="the engine's start event")
        assert events[0]["kind"] == "start"
    finally:
        assert node.stop() == 0
        token.undeclare()


def test_a_node_stopped_at_the_gate_ends_cleanly_without_starting(hub):
    node = Node(node_config(hub, "echo", f"{ECHO}:Echo", start_gate=GATE))
    try:
        hub.subscribe(f"{node.base}/@trace", f"{node.base}/@heartbeat")
        wait_ready(hub, node)
    finally:
        code = node.stop()
    assert code == 0, node.process.stderr
    assert trace(hub, node) == []


@pytest.mark.parametrize("gate", ["", "iota/test/@go/*", 7])
def test_a_bad_gate_in_the_config_is_one_clear_line(gate):
    with pytest.raises(ConfigError, match="start_gate must be a liveliness key without wildcards"):
        from_dict({"system": "s", "path": "p", "source": {"kind": "python", "ref": "m:C"}, "start_gate": gate})
