"""`iotad run` with real node processes on loopback: restarts after kill -9 and after a freeze,
Ctrl-C, a launcher killed with SIGKILL, restart policies, events on @launcher."""
import os
import re
import signal
import sys
import time
from pathlib import Path

import pytest
import zenoh

from iotad.node_host import wire
from iotad.launcher.options import LaunchOptions
from iotad.launcher.run.recorder_supervision import RECORDER_MODULE
from iotad.launcher.run.tally import count_trace
from iotad.launcher.run.supervision import Launcher
from iotad.launcher.system.system_file import load_system
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import IOTAS, Observer, children_of, free_port, gone, launcher, pair_system, wait_until

STUB = Path(__file__).resolve().parents[1] / "launcher_stub_node.py"


def node_pid(launcher_pid: int, name: str) -> int | None:
    for pid, cmdline in children_of(launcher_pid).items():
        if f"/{name}.json" in cmdline:
            return pid
    return None


@pytest.fixture
def observed_pair(tmp_path):
    """A running pair system (src -> dst), its launcher process and an observer; both nodes live."""
    def start(extra_system: str = ""):
        port = free_port()
        system_file = pair_system(tmp_path, port, extra_system, extra_node='max_restarts = 3')
        observer = Observer("pair", f"tcp/127.0.0.1:{port}")
        started.append(observer)
        context = launcher(system_file, "--no-record")
        proc = context.__enter__()
        started.append(context)
        assert observer.wait_all_alive(("src", "dst"), 15), proc.output.read_text()
        # live to the launcher too, not only to the observer: a token reaches each session over
        # its own link, and a node frozen (SIGSTOP) between the two never reaches the launcher's,
        # which then kills it after start_timeout as a node that never went live, not as a stale one
        assert wait_until(lambda: all(f"{name}: live (pid" in proc.output.read_text() for name in ("src", "dst")), 15), \
            proc.output.read_text()
        return proc, observer

    started = []
    yield start
    for thing in reversed(started):
        if isinstance(thing, Observer):
            thing.close()
        else:
            thing.__exit__(None, None, None)


def test_a_node_terminated_from_outside_is_restarted_as_a_killed_one(observed_pair):
    """SIGTERM from anyone but the launcher (kill, a service manager) ends the node with status
    143, a kill's: restart = "on-failure" restarts it, where a clean exit 0 left it dead."""
    proc, observer = observed_pair()
    pid = node_pid(proc.pid, "dst")
    assert pid is not None
    os.kill(pid, signal.SIGTERM)
    restart = observer.wait_event(lambda e: e["event"] == "restart" and e["node"] == "dst", 10)
    assert restart is not None and restart["pid"] != pid, proc.output.read_text()
    assert observer.wait_alive("dst", True, 10) is not None
    assert "dst: exit 143 (SIGTERM) after" in proc.output.read_text()


def test_kill9_node_is_restarted_after_its_backoff_and_live_again(observed_pair):
    proc, observer = observed_pair()
    pid = node_pid(proc.pid, "dst")
    assert pid is not None
    killed_at, killed_ns = time.monotonic(), time.time_ns()
    os.kill(pid, signal.SIGKILL)
    lost = observer.wait_alive("dst", False, 5)
    back = observer.wait_alive("dst", True, 5)
    assert lost is not None and back is not None, proc.output.read_text()
    restart_time = back - killed_at
    restart = observer.wait_event(lambda e: e["event"] == "restart" and e["node"] == "dst", 5)
    assert restart is not None and restart["restarts"] == 1 and restart["pid"] != pid
    # what the launcher contributes (exit seen, backoff 0.1 s, spawn) and what the node's own
    # start-up takes (interpreter, imports, zenoh session, token), so a slow box shows which
    spawned = (restart["t_ns"] - killed_ns) / 1e9
    split = (f"kill -9 -> liveliness token lost after {(lost - killed_at) * 1000:.0f} ms, new process spawned "
             f"after {spawned * 1000:.0f} ms (launcher, 100 ms backoff included), live again after "
             f"{restart_time * 1000:.0f} ms (node start-up {(restart_time - spawned) * 1000:.0f} ms)")
    print("\n" + split)  # the figures, for a person; a test bounds no wall-clock time
    assert spawned >= 0.1, split  # the launcher waited out the node's backoff before spawning it again
    new_pid = node_pid(proc.pid, "dst")
    assert new_pid == restart["pid"] and not gone(new_pid)
    # the new process's heartbeats carry the launcher's count, for tools attached later (iotad top)
    beats = observer.session.declare_subscriber("iota/pair/dst/@heartbeat", zenoh.handlers.FifoChannel(8))
    beat = wire.decode(beats.handler.recv().payload.to_bytes())
    assert beat["restarts"] == 1, beat


def test_frozen_node_is_killed_and_restarted(observed_pair):
    """SIGSTOP keeps the process and its liveliness token (until zenoh's lease): only the stale
    heartbeat tells the launcher that the node no longer runs."""
    proc, observer = observed_pair("heartbeat_timeout = 1.0")
    pid = node_pid(proc.pid, "src")
    frozen_at = time.monotonic()
    os.kill(pid, signal.SIGSTOP)
    try:
        stale = observer.wait_event(lambda e: e["event"] == "stale" and e["node"] == "src", 5)
        assert stale is not None, proc.output.read_text()
        back = observer.wait_alive("src", True, 5)
        assert back is not None
        print(f"\nfrozen node: detected and restarted, live again {back - frozen_at:.2f} s after SIGSTOP")
        assert wait_until(lambda: gone(pid), 5)
        assert node_pid(proc.pid, "src") not in (None, pid)
        # the exit line says why it was killed, then how long it had run
        # (the reason may carry its own "(none since it went live)" when SIGSTOP beat the first heartbeat)
        exits = [line for line in proc.output.read_text().splitlines() if "src: killed by SIGKILL (no heartbeat for" in line]
        assert exits and re.search(r"\(no heartbeat for [\d.]+ s[^;]*\) after [\d.]+ s", exits[0]), proc.output.read_text()
    finally:
        if not gone(pid):
            os.kill(pid, signal.SIGKILL)


@pytest.mark.parametrize("signum, status, said", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")],
                         ids=["ctrl-c", "sigterm"])
def test_signal_stops_every_child(observed_pair, signum, status, said):
    """SIGTERM (a service manager, `kill`) stops exactly like Ctrl-C; the status says which."""
    proc, observer = observed_pair()
    kids = children_of(proc.pid)
    assert len(kids) == 2
    proc.send_signal(signum)
    assert proc.wait(15) == status
    assert all(gone(pid) for pid in kids), kids
    output = proc.output.read_text()
    assert f"{said}: stopping every node" in output and output.count("stopped (exit 0)") == 2, output


def test_node_frozen_before_its_first_heartbeat_is_killed(tmp_path):
    """The race behind a once-flaky frozen-node test: a node whose token is up but whose first
    heartbeat never comes (frozen in between) was never judged stale. A stand-in plays it."""
    path = tmp_path / "mute.toml"
    path.write_text(f"""
[system]
name = "mute"
heartbeat_timeout = 0.5
[system.endpoints]
listen = ["tcp/127.0.0.1:{free_port()}"]
[[node]]
name = "n"
python = "{IOTAS}:Rogue"
params = {{ token = true, exit_after = 60 }}
max_restarts = 1
backoff = 0.01
""")
    lines = []
    run = Launcher(load_system(path), LaunchOptions(until=30, live_table=False, log_dir=str(tmp_path / "logs"),
                                                    node_argv=lambda config: [sys.executable, str(STUB), config]))
    run.view.line = lines.append
    assert run.run() == 1, lines
    kills = [line for line in lines if "none since it went live" in line and "killing" in line]
    assert len(kills) == 2 and run.runs["n"].restarts == 1, lines
    assert any("gave up after 1 restarts" in line for line in lines), lines


def test_sigkilled_launcher_leaves_no_orphans(tmp_path):
    """The recorder too: it is a child like the nodes. It is interrupted rather than killed, so
    the recording it leaves is complete (summary and footer), up to the launcher's death."""
    port = free_port()
    system_file = pair_system(tmp_path, port)
    observer = Observer("pair", f"tcp/127.0.0.1:{port}")
    try:
        with launcher(system_file, "-o", str(tmp_path / "rec.mcap")) as proc:
            assert observer.wait_alive("dst", True, 15) is not None, proc.output.read_text()
            kids = children_of(proc.pid)
            assert len(kids) == 3, kids  # two nodes and the recorder
            assert any(RECORDER_MODULE in cmd for cmd in kids.values())  # the recording layer's module, not the CLI
            proc.kill()
            proc.wait(5)
            assert wait_until(lambda: all(gone(pid) for pid in kids), 10), \
                {pid: cmd for pid, cmd in kids.items() if not gone(pid)}
        recording = read_recording(str(tmp_path / "rec.mcap"))
        assert recording.complete, recording.path
    finally:
        observer.close()


def stub_system(tmp_path, restart: str, exit_code: int, max_restarts: int = 2) -> Path:
    path = tmp_path / f"stub-{restart}-{exit_code}.toml"
    path.write_text(f"""
[system]
name = "stub"
[system.endpoints]
listen = ["tcp/127.0.0.1:{free_port()}"]
[[node]]
name = "n"
python = "{IOTAS}:Stub"
params = {{ exit_code = {exit_code}, exit_after = 0.05 }}
restart = "{restart}"
max_restarts = {max_restarts}
backoff = 0.01
""")
    return path


@pytest.mark.parametrize("restart, exit_code, restarts, state, code", [
    ("on-failure", 3, 2, "failed", 1),
    ("on-failure", 0, 0, "exited", 0),
    ("always", 0, 2, "failed", 1),
    ("never", 3, 0, "failed", 1),
])
def test_restart_policies(tmp_path, restart, exit_code, restarts, state, code):
    """With a stand-in node host that exits on cue: the launcher ends once nothing will run again."""
    system = load_system(stub_system(tmp_path, restart, exit_code))
    lines = []
    run = Launcher(system, LaunchOptions(until=20, live_table=False, log_dir=str(tmp_path / "logs"),
                                         node_argv=lambda config: [sys.executable, str(STUB), config]))
    run.view.line = lines.append
    started = time.monotonic()
    assert run.run() == code, lines
    assert time.monotonic() - started < 10
    node = run.runs["n"]
    assert (node.restarts, node.state) == (restarts, state), lines
    if restarts:
        assert any("gave up after 2 restarts" in line for line in lines), lines


def test_node_without_liveliness_is_killed_after_start_timeout(tmp_path):
    """A node that runs but never declares its token (here: a stand-in that just sleeps)."""
    path = stub_system(tmp_path, "on-failure", 0, max_restarts=1)
    path.write_text(path.read_text().replace("exit_after = 0.05", "exit_after = 30")
                    .replace('name = "stub"', 'name = "stub"\nstart_timeout = 0.5'))
    lines = []
    run = Launcher(load_system(path), LaunchOptions(until=20, live_table=False, log_dir=str(tmp_path / "logs"),
                                                    node_argv=lambda config: [sys.executable, str(STUB), config]))
    run.view.line = lines.append
    started = time.monotonic()
    assert run.run() == 1, lines
    assert time.monotonic() - started < 5, lines
    assert sum("no liveliness token within 0.5 s: killing" in line for line in lines) == 2, lines
    assert run.runs["n"].restarts == 1


def test_summary_counters_stay_bounded(tmp_path):
    """A counter output carries a new value each time: the launcher counts a bounded set of
    labels per channel over a long run, and the summary still reads."""
    run = Launcher(load_system(pair_system(tmp_path, free_port())),
                   LaunchOptions(log_dir=str(tmp_path / "logs"), live_table=False))
    for n in range(10_000):
        run.tally.channel("iota/pair/src/out", n)
    run.tally.channel("iota/pair/src/out", "<malformed>")
    counts = run.tally.values["iota/pair/src/out"]
    assert len(counts) <= 33 and sum(counts.values()) == 10_001
    (line,) = [line for line in run.summary() if "src.out" in line]
    assert "10001 events: 32+ distinct values" in line, line


def test_summary_reads_trace_bursts_and_single_events(tmp_path):
    """A @trace sample is a burst (list of events) or one event (dict): the launcher counts the
    outputs and violations of both, and skips what is malformed (a bad element, a bad payload)."""
    from types import SimpleNamespace

    run = Launcher(load_system(pair_system(tmp_path, free_port())),
                   LaunchOptions(log_dir=str(tmp_path / "logs"), live_table=False))

    def sample(payload):
        return SimpleNamespace(key_expr="iota/pair/src/@trace", payload=SimpleNamespace(to_bytes=lambda: payload))

    out = {"t": 0.1, "iota": "src", "action": "out", "index": None, "kind": "output", "value": 1,
           "key": "iota/pair/src/out", "seq": 0, "send_ns": 1}
    bad = {"t": 0.2, "iota": "src", "action": "x", "index": None, "kind": "violation",
           "value": {"violation": "v", "message": "m"}}
    count_trace(run.tally, "pair", sample(wire.encode_burst([wire.start_event(0.0, "src", 1.0, 1), out, 7, out, bad])))
    count_trace(run.tally, "pair", sample(wire.encode(out)))  # the old form: one event a sample
    count_trace(run.tally, "pair", sample(b"\xc1"))
    count_trace(run.tally, "pair", sample(wire.encode("neither")))
    assert sum(run.tally.values["iota/pair/src/out"].values()) == 3
    assert run.tally.violations["src"] == 1
