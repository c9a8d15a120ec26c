"""`iotad ls/echo/pub/hz` against a live node process, and their behaviour with no peer."""
import json
import socket
import subprocess
import sys

import pytest

from node_harness import ECHO, ROOT, Hub, Node, node_config, wait_ready


def iotad(*args, timeout=30, stdin=None):
    return subprocess.run([sys.executable, "-m", "iotad", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, input=stdin)


@pytest.fixture(scope="module")
def live():
    hub = Hub()
    node = None
    try:
        node = Node(node_config(hub, "echo", f"{ECHO}:Echo", system="intro"))
        hub.subscribe(f"{node.base}/@heartbeat")
        wait_ready(hub, node)
        yield hub, node
    finally:
        if node is not None:
            node.stop()
        hub.close()


def test_ls_lists_the_node_and_its_channels(live):
    hub, node = live
    result = iotad("ls", "--system", "intro", "--json", "--connect", hub.endpoint)
    assert result.returncode == 0, result.stderr
    (entry,) = [json.loads(line) for line in result.stdout.splitlines()]
    assert entry["path"] == "echo" and entry["pid"] == node.process.pid
    assert entry["host"] == socket.gethostname()  # a system on one machine: the machine's name
    assert {c["name"]: c["direction"] for c in entry["channels"]} == {"inp": "input", "out": "output"}
    text = iotad("ls", "--connect", hub.endpoint)
    assert "intro/echo" in text.stdout and "iota/intro/echo/out" in text.stdout
    assert f"intro/echo  host {socket.gethostname()}  pid {node.process.pid}" in text.stdout


def echo_while_publishing(live, key: str, count: int, value: str, stdin: str | None = None) -> list[dict]:
    """`iotad echo KEY --count N --json` while `iotad pub` sends `value` into the node's input:
    echo is ready once it receives, so publish until it has seen N (bounded by pub --count)."""
    hub, node = live
    echo = subprocess.Popen([sys.executable, "-m", "iotad", "echo", f"{node.base}/{key}", "--count", str(count),
                             "--json", "--timeout", "20", "--connect", hub.endpoint],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        pub = iotad("pub", f"{node.base}/inp", value, "--count", "40", "--rate", "20", "--connect", hub.endpoint,
                    stdin=stdin)
        assert pub.returncode == 0, pub.stderr
        out, err = echo.communicate(timeout=25)
    finally:
        if echo.poll() is None:
            echo.kill()
            echo.wait()
    assert echo.returncode == 0, err
    return [json.loads(line) for line in out.splitlines()]


def test_pub_into_the_node_and_echo_its_output(live):
    _, node = live
    records = echo_while_publishing(live, "out", 3, "5")
    assert len(records) == 3 and all(r["value"] == 5 and r["key"] == f"{node.base}/out" for r in records)
    assert [r["seq"] for r in records] == list(range(records[0]["seq"], records[0]["seq"] + 3))


def test_pub_takes_the_value_from_a_file_or_standard_input(live, tmp_path):
    (tmp_path / "value.json").write_text("  7\n")
    from_file = echo_while_publishing(live, "out", 2, f"@{tmp_path / 'value.json'}")
    from_stdin = echo_while_publishing(live, "out", 2, "-", stdin="8\n")
    assert [r["value"] for r in from_file] == [7, 7] and [r["value"] for r in from_stdin] == [8, 8]


def test_echo_flags_gaps():
    from iotad.cli.commands.echo import GapTracker

    gaps = GapTracker()
    assert [gaps.see("k", s) for s in (0, 1, 4, 5, 0)] == [0, 0, 2, 0, -1]
    # @trace bursts: a sequence number counts events, a burst of n takes n of them
    assert [gaps.see("t", s, n) for s, n in ((0, 3), (3, 2), (5, 1), (9, 4), (2, 1))] == [0, 0, 0, 3, -1]


def test_echo_json_says_gap_or_restart_in_words():
    from iotad.cli.commands.echo import json_record

    assert json_record("k", 4, 10, 1, 2, None) == {"key": "k", "seq": 4, "send_ns": 10, "value": 1, "gap": 2}
    assert json_record("k", 0, 10, 1, -1, None) == {"key": "k", "seq": 0, "send_ns": 10, "value": 1, "restarted": True}
    assert "gap" not in json_record("k", 1, 10, 1, 0, None)


def test_echo_prints_each_event_of_a_trace_burst(live):
    records = echo_while_publishing(live, "@trace", 4, "6")
    assert len(records) == 4 and all(isinstance(r["value"], dict) and r["value"]["iota"] == "echo" for r in records)
    assert [r["seq"] for r in records] == list(range(records[0]["seq"], records[0]["seq"] + 4))


def test_hz_reports_the_heartbeat_rate(live):
    hub, node = live
    result = iotad("hz", f"{node.base}/@heartbeat", "--count", "2", "--every", "0.6", "--connect", hub.endpoint)
    assert result.returncode == 0, result.stderr
    rate = float(result.stdout.split("average rate:")[-1].split()[0])
    assert 2 < rate < 50  # heartbeat period 0.1 s; loose: this is not a timing test


@pytest.mark.parametrize("command", [["ls"], ["echo", "iota/**"], ["pub", "iota/x/y", "1"], ["hz", "iota/**"]])
def test_missing_peer_is_a_clear_error(command):
    result = iotad(*command, "--connect", "tcp/127.0.0.1:9", "--connect-timeout", "0.5")
    assert result.returncode == 2
    assert "no zenoh peer at tcp/127.0.0.1:9" in result.stderr and "Traceback" not in result.stderr


def test_echo_past_its_timeout_says_what_it_got(live):
    hub, node = live
    quiet = iotad("echo", f"{node.base}/nothing-here", "--timeout", "0.5", "--connect", hub.endpoint)
    assert quiet.returncode == 1
    assert quiet.stderr.strip() == f"iotad echo: timeout: no message on {node.base}/nothing-here within 0.5 s"
    some = iotad("echo", f"{node.base}/@heartbeat", "--count", "1000", "--timeout", "0.5", "--connect", hub.endpoint)
    assert some.returncode == 1 and " of the 1000 messages wanted on " in some.stderr, some.stderr


def test_top_once_says_when_no_node_showed_itself(live):
    hub, node = live
    there = iotad("top", "--once", "1", "--system", "intro", "--connect", hub.endpoint)
    assert there.returncode == 0 and "echo" in there.stdout, there.stderr
    nobody = iotad("top", "--once", "1", "--system", "nosuch", "--connect", hub.endpoint)
    assert nobody.returncode == 1
    assert nobody.stderr.strip() == "iotad top: no node of system 'nosuch' showed itself within 1 s"
