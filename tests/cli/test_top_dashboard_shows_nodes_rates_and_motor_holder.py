"""`iotad top`: the dashboard model fed by hand (restarts, holder, rates, latency, bad samples),
and the real command in a pseudo-terminal against a running Figure 2 system."""
import fcntl
import os
import pty
import re
import select
import socket
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

from launcher_helpers import free_port, launcher, wait_until

from iotad.cli.dashboard import Dashboard

ROOT = Path(__file__).resolve().parents[2]


class FakeClock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def test_a_token_that_comes_back_is_a_restart_and_a_missing_one_shows_gone():
    board = Dashboard("figure2", clock=FakeClock())
    board.alive("scheduler", True)
    board.alive("scheduler", False)
    assert board.node_rows()[0][:4] == ("scheduler", "?", "gone", "0")
    board.alive("scheduler", True)
    board.alive("scheduler", True)  # a repeated put is not a restart
    assert board.node_rows()[0][:4] == ("scheduler", "?", "alive", "1")


def test_restarts_before_the_tool_began_come_from_the_heartbeat():
    """A node restarted twice before `iotad top` started says so in its heartbeats (the
    launcher's count); a restart top sees itself adds one; an old heartbeat takes none away."""
    board = Dashboard("figure2", clock=FakeClock())
    board.alive("vision", True)
    board.heartbeat("vision", {"t": 5.0, "firings": 9, "queue": 0, "restarts": 2})
    assert board.node_rows()[0][:4] == ("vision", "?", "alive", "2")
    board.alive("vision", False)
    board.alive("vision", True)
    assert board.node_rows()[0][3] == "3"
    board.heartbeat("vision", {"t": 6.0, "firings": 1, "queue": 0, "restarts": 2})  # a late one of the old process
    board.heartbeat("vision", {"t": 6.1, "firings": 1, "queue": 0, "restarts": 3})
    board.heartbeat("vision", {"t": 6.2, "firings": 2, "queue": 0, "restarts": True})  # not a count
    assert board.node_rows()[0][3] == "3"


def test_the_holder_follows_schedule_and_commit_and_is_named_from_the_spec():
    board = Dashboard("figure2", clock=FakeClock())
    board.spec("scheduler", {"channels": [
        {"name": "req", "direction": "input", "bound": {"req/0": ["iota/figure2/vision/req"],
                                                        "req/1": ["iota/figure2/arm/manipulation/req"]}}]})
    assert board.holder_lines() == ["scheduler: free"]
    board.trace("scheduler", [{"t": 1.5, "kind": "internal", "action": "schedule", "index": 1}])
    assert board.holder_lines() == ["scheduler: arm/manipulation (since t=1.50)"]
    board.trace("scheduler", [{"t": 2.0, "kind": "internal", "action": "schedule", "index": 0}])  # preempts
    assert board.holder_lines() == ["scheduler: vision (since t=2.00)"]
    board.trace("scheduler", [{"t": 3.0, "kind": "internal", "action": "commit", "index": 1}])  # not the holder
    assert board.holder_lines() == ["scheduler: vision (since t=2.00)"]
    board.trace("scheduler", [{"t": 3.5, "kind": "internal", "action": "commit", "index": 0}, "junk"])
    assert board.holder_lines() == ["scheduler: free (since t=3.50)"]
    assert board.ignored == 1
    board.alive("scheduler", True)
    board.trace("scheduler", [{"t": 4.0, "kind": "internal", "action": "schedule", "index": 0}])
    board.alive("scheduler", False)  # the system stopped, or the scheduler died: no longer known
    assert board.holder_lines() == ["scheduler: vision (since t=4.00), last known: the scheduler is gone"]


def test_rates_and_p99_latency_cover_the_last_window_only():
    clock = FakeClock()
    board = Dashboard("s", window=5.0, clock=clock)
    for k in range(100):
        clock.now = 1000.0 + k * 0.01
        board.message("a/out", send_ns=int((clock.now - (0.050 if k >= 98 else 0.001)) * 1e9))
    assert board.channel_rows() == [("a/out", "20.0", "50.00", "100")]
    clock.now += 10  # all out of the window
    assert board.channel_rows() == [("a/out", "0.0", "-", "100")]


def test_violations_are_counted_per_node_and_listed():
    board = Dashboard("s", clock=FakeClock())
    board.trace("vision", [{"t": 1.0, "kind": "violation", "action": "req",
                            "value": {"violation": "switching_time", "message": "too soon"}}])
    assert board.node_rows()[0][-1] == "1"
    assert list(board.violations)[0][1:4] == ("vision", "req", "switching_time")


def read_screen(fd, until, timeout):
    screen, deadline = b"", time.monotonic() + timeout
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                screen += os.read(fd, 65536)
            except OSError:
                break
        text = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.decode(errors="replace"))
        if until(text):
            return text
    return re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", screen.decode(errors="replace"))


def test_iotad_top_in_a_terminal_shows_the_nodes_and_who_holds_the_motors(tmp_path):
    port = free_port()
    text = (ROOT / "examples/figure2.toml").read_text()
    text = text.replace("../nodes/", f"{ROOT}/nodes/").replace('"requesters.py:', f'"{ROOT}/examples/requesters.py:')
    system = tmp_path / "figure2.toml"
    system.write_text(text)
    with launcher(system, "--port", str(port), "--until", "30", "--after-live", "--no-record") as proc:
        assert wait_until(lambda: "manipulation: started" in proc.output.read_text(), 20), proc.output.read_text()
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 150, 0, 0))  # rows, columns
        env = dict(os.environ, COLUMNS="120", LINES="40", TERM="xterm")
        top = subprocess.Popen([sys.executable, "-m", "iotad", "top", "--system", "figure2",
                                "--connect", f"tcp/127.0.0.1:{port}", "--refresh", "0.2"],
                               stdin=slave, stdout=slave, stderr=slave, env=env, start_new_session=True)
        os.close(slave)
        try:
            screen = read_screen(master, lambda s: re.search(r"motors held by: scheduler: (vision|manipulation)", s)
                                 and "scheduler/mdl_command" in s, timeout=25)
        finally:
            top.terminate()
            try:
                top.wait(10)
            except subprocess.TimeoutExpired:
                top.kill()
                top.wait(5)
            os.close(master)
    # the host column: a system on one machine shows the machine's name
    assert re.search(r"scheduler\s*│\s*" + re.escape(socket.gethostname()[:12]) + r"\S*\s*│\s*alive", screen), \
        screen[-2000:]
    assert re.search(r"motors held by: scheduler: (vision|manipulation)", screen), screen[-2000:]
    assert "scheduler/mdl_command" in screen
