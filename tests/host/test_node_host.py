"""The node host as a process on zenoh: echo, violations, heartbeat, @spec, clean exit."""
import json
import signal
import subprocess
import sys
import time

import pytest

from iotad.node_host import wire
from node_harness import ECHO, ROOT, Node, node_config, wait_for, wait_ready


@pytest.fixture
def start_node(hub):
    nodes = []

    def start(path, ref, **extra):
        node = Node(node_config(hub, path, ref, **extra))
        nodes.append(node)
        hub.subscribe(f"{node.base}/out", f"{node.base}/@trace", f"{node.base}/@heartbeat")
        wait_ready(hub, node)
        return node

    try:
        yield start
    finally:
        for node in nodes:
            node.stop()


def publish(hub, key, payload: bytes, seq: int = 0):
    hub.session.put(key, payload, attachment=wire.encode_attachment(seq))


def violations(hub, node, code):
    return [e for e in hub.values(f"{node.base}/@trace")
            if e["kind"] == "violation" and e["value"]["violation"] == code]


def test_echo_node_answers_with_seq_and_trace(hub, start_node):
    node = start_node("echo", f"{ECHO}:Echo")
    for k in range(3):
        publish(hub, f"{node.base}/inp", wire.encode(10 + k), k)
    wait_for(lambda: len(hub.values(f"{node.base}/out")) == 3, what="three echoes")
    assert hub.values(f"{node.base}/out") == [10, 11, 12]
    metas = [meta for key, _, meta in hub.drain() if key == f"{node.base}/out"]
    assert [m[0] for m in metas] == [0, 1, 2]  # the sender's sequence numbers
    assert all(abs(m[1] - time.time_ns()) < 60e9 for m in metas)
    trace = wait_for(lambda: [e for e in hub.values(f"{node.base}/@trace") if e["kind"] != "violation"]
                     if len(hub.values(f"{node.base}/@trace")) >= 6 else None, what="six trace events")
    assert [e["value"] for e in trace if e["kind"] == "input"] == [10, 11, 12]
    assert [e["value"] for e in trace if e["kind"] == "output"] == [10, 11, 12]
    assert all(e["iota"] == "echo" and e["t"] > 0 for e in trace)


def test_bad_inputs_are_violations_and_the_node_keeps_serving(hub, start_node):
    node = start_node("echo", f"{ECHO}:Echo")
    key = f"{node.base}/inp"
    publish(hub, key, b"\xc1\xc1")                 # not msgpack
    publish(hub, key, wire.encode("seven"), 1)     # wrong type
    publish(hub, key, wire.encode(-3), 2)          # out of range
    publish(hub, key, wire.encode(7), 3)           # legitimate
    hub.wait_value(f"{node.base}/out", lambda v: v == 7, what="the legitimate echo")
    wait_for(lambda: violations(hub, node, "malformed_payload"), what="malformed_payload violation")
    bad = wait_for(lambda: len(violations(hub, node, "bad_value")) == 2 and violations(hub, node, "bad_value"),
                   what="two bad_value violations")
    assert "expected int" in bad[0]["value"]["message"] and "outside range" in bad[1]["value"]["message"]
    assert hub.values(f"{node.base}/out") == [7]
    assert node.process.poll() is None


def test_flood_faster_than_switching_time(hub, start_node):
    # switching time 1 unit = 0.2 s: of a burst of ten inputs, only the first is accepted
    node = start_node("paced", f"{ECHO}:PacedEcho", time_unit=0.2)
    for k in range(10):
        publish(hub, f"{node.base}/inp", wire.encode(k), k)
    wait_for(lambda: len(violations(hub, node, "switching_time")) >= 5, what="switching_time violations")
    hub.wait_value(f"{node.base}/out", lambda v: v == 0, what="the first input's echo")
    # once the switching time has passed, a legitimate input is served again
    wait_for(lambda: (publish(hub, f"{node.base}/inp", wire.encode(99), 100) or True)
             and 99 in hub.values(f"{node.base}/out"), timeout=10, interval=0.25, what="echo after the flood")
    assert node.process.poll() is None


def test_heartbeat_counts_firings(hub, start_node):
    node = start_node("echo", f"{ECHO}:Echo")
    publish(hub, f"{node.base}/inp", wire.encode(1))
    beat = hub.wait_value(f"{node.base}/@heartbeat", lambda v: v["firings"] >= 1, what="a heartbeat after a firing")
    assert set(beat) == {"t", "firings", "queue", "restarts"} and beat["queue"] >= 0
    assert beat["restarts"] == 0  # a bare config: its first process


def test_spec_query_describes_the_node(hub, start_node):
    node = start_node("sched", f"{ROOT / 'examples' / 'scheduler.py'}:Scheduler", params={"N": 3, "T": 0.5},
                      inputs={"req/0": ["iota/test/vision/req"]})
    replies = [r.ok for r in hub.session.get(f"{node.base}/@spec", timeout=5) if r.ok is not None]
    assert len(replies) == 1
    spec = wire.decode(replies[0].payload.to_bytes())
    assert spec["path"] == "sched" and spec["params"] == {"N": 3, "T": 0.5}
    assert "class Scheduler" in spec["text"]
    channels = {c["name"]: c for c in spec["channels"]}
    assert channels["req"]["keys"] == [f"{node.base}/req/{k}" for k in range(3)]
    assert channels["req"]["bound"]["req/0"] == ["iota/test/vision/req"]
    assert channels["mdl_command"]["direction"] == "output" and channels["mdl_command"]["type_name"] == "mode"
    assert "schedule" not in channels  # internal channels are not on the wire


def test_liveliness_token(hub, start_node):
    node = start_node("echo", f"{ECHO}:Echo")
    tokens = [str(r.ok.key_expr) for r in hub.session.liveliness().get("iota/test/**/@alive", timeout=5)
              if r.ok is not None]
    assert tokens == [f"{node.base}/@alive"]


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 128 + signal.SIGTERM), (signal.SIGINT, 0)])
def test_signal_exits_cleanly(hub, start_node, signum, status):
    """SIGINT is its launcher's stop: exit 0. SIGTERM comes from anyone else (kill, a service
    manager): a clean exit too, with a kill's status, so that restart = "on-failure" restarts it."""
    node = start_node("echo", f"{ECHO}:Echo")
    started = time.monotonic()
    node.process.send_signal(signum)
    assert node.process.wait(timeout=5) == status
    assert time.monotonic() - started < 5
    out, err = node.process.communicate()
    assert out == b"" and err == b""


def run_node(*args, timeout=30):
    return subprocess.run([sys.executable, "-m", "iotad.node_host", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout)


def test_bad_config_is_one_line_on_stderr(tmp_path):
    cases = ["{not json", json.dumps({"path": "x", "source": {"kind": "python", "ref": "a:b"}}),
             json.dumps({"system": "s", "path": "x", "source": {"kind": "cobol"}})]
    for text in cases:
        result = run_node("--config-json", text)
        assert result.returncode == 2 and result.stdout == ""
        assert len(result.stderr.strip().splitlines()) == 1 and "error" in result.stderr
    result = run_node(str(tmp_path / "missing.json"))
    assert result.returncode == 2 and "cannot read config" in result.stderr


def test_spec_that_fails_to_load_is_reported(tmp_path):
    broken = tmp_path / "broken.py"
    broken.write_text("from iotad import Iota\nclass Broken(Iota):\n    x = undefined_name\n")
    config = {"system": "s", "path": "b", "source": {"kind": "python", "ref": f"{broken}:Broken"}}
    result = run_node("--config-json", json.dumps(config))
    assert result.returncode == 2 and result.stdout == ""
    assert "cannot load its IOTA" in result.stderr and "undefined_name" in result.stderr
    config["source"]["ref"] = f"{ECHO}:Echo"
    config["inputs"] = {"nope": ["iota/s/x/y"]}
    result = run_node("--config-json", json.dumps(config))
    assert result.returncode == 2 and "unknown input channel" in result.stderr


def test_trace_opens_with_the_engine_start_event(hub, start_node):
    node = start_node("echo", f"{ECHO}:Echo")
    publish(hub, f"{node.base}/inp", wire.encode(5))
    trace = wait_for(lambda: len(hub.values(f"{node.base}/@trace")) >= 3 and hub.values(f"{node.base}/@trace"),
                     what="start, input and output on @trace")
    first = trace[0]
    assert (first["kind"], first["action"], first["iota"]) == ("start", "@start", "echo")
    assert first["value"]["pid"] == node.process.pid
    assert 0 < first["t"] <= trace[1]["t"]
    assert [e["kind"] for e in trace[1:3]] == ["input", "output"]
