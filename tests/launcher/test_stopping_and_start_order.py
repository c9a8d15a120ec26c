"""Final review of the node host and the launcher: defects found, each pinned by a test."""
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from iotad.launcher.options import LaunchOptions
from iotad.launcher.run.supervision import Launcher
from iotad.launcher.system.system_file import load_system
from launcher_helpers import IOTAS, ROOT, free_port, gone, wait_until

STUB = Path(__file__).resolve().parents[1] / "launcher_stub_node.py"


def test_sigterm_while_a_host_launcher_waits_for_the_hub_origin_stops_at_once(tmp_path):
    """A launcher for a host that does not hold the hub asks the hub launcher for the clock
    origin for up to start_timeout seconds; a SIGTERM meanwhile must stop it then, not after."""
    path = tmp_path / "split.toml"
    path.write_text(f"""
[system]
name = "split"
hub_host = "brain"
start_timeout = 12.0
[system.endpoints]
listen = ["tcp/127.0.0.1:{free_port()}"]

[[node]]
name = "src"
python = "{IOTAS}:Source"
host = "brain"

[[node]]
name = "sink"
python = "{IOTAS}:Sink"
host = "arm"

[[bind]]
from = "src.out"
to = "sink.inp"
""")
    proc = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(path), "--insecure", "--host", "arm", "--plain",
                             "--log-dir", str(tmp_path / "logs")], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        for line in proc.stdout:  # in _ask_origin: no hub launcher runs
            if "for the hub launcher's clock origin" in line:
                break
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=20)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 143, out
    assert took < 4.0, f"stopped {took:.1f} s after SIGTERM:\n{out}"
    assert "no hub launcher answered" not in out, out


def test_a_second_ctrl_c_during_the_stop_skips_the_waiting(tmp_path):
    """docs/failures.md: "A second signal skips the waiting." The usual case is a second Ctrl-C
    pressed while the launcher already waits for a node that ignores the first one."""
    path = tmp_path / "stubborn.toml"
    path.write_text(f"""
[system]
name = "stubborn"
[system.endpoints]
listen = ["tcp/127.0.0.1:{free_port()}"]

[[node]]
name = "n"
python = "{IOTAS}:Rogue"
params = {{ ignore_signals = true, exit_after = 60 }}
""")
    run = Launcher(load_system(path), LaunchOptions(live_table=False, log_dir=str(tmp_path / "logs"), until=30,
                                                    node_argv=lambda config: [sys.executable, str(STUB), config],
                                                    stop_timeouts=(4.0, 4.0)))
    lines: list[tuple[float, str]] = []
    run.view.line = lambda text: lines.append((time.monotonic(), text))
    log = tmp_path / "logs" / "n.log"
    signals: list[float] = []

    def press_ctrl_c_twice():
        if not wait_until(lambda: log.exists() and "ready" in log.read_text(), 20):
            return
        signals.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)  # the launcher is now waiting out the node's SIGINT timeout
        signals.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c_twice, daemon=True)
    presser.start()
    code = run.run()
    ended = time.monotonic()
    presser.join(5)
    texts = [text for _, text in lines]
    assert code == 130, texts
    assert len(signals) == 2, texts
    assert ended - signals[1] < 2.0, f"ended {ended - signals[1]:.1f} s after the second Ctrl-C: {texts}"
    assert gone(run.runs["n"].child.pid)


def test_a_heartbeat_period_not_below_the_heartbeat_timeout_is_a_check_error(tmp_path):
    """Every node would be killed as frozen between two of its heartbeats, over and over."""
    import pytest

    from iotad.launcher.system.system_file import SystemFileError

    def system(period: float, timeout: float) -> Path:
        path = tmp_path / "beat.toml"
        path.write_text(f'[system]\nname = "beat"\nheartbeat_period = {period}\nheartbeat_timeout = {timeout}\n'
                        f'[[node]]\nname = "d"\npython = "{IOTAS}:Stub"\n')
        return path

    with pytest.raises(SystemFileError, match="heartbeat_period"):
        load_system(system(5.0, 3.0))
    with pytest.raises(SystemFileError, match="heartbeat_period"):
        load_system(system(3.0, 3.0))
    assert load_system(system(1.0, 3.0)).heartbeat_period == 1.0


def test_a_node_waiting_on_a_node_that_failed_for_good_is_reported_and_the_run_ends(tmp_path):
    """`after = ["a"]` with `a` given up on: `b` can never start. It used to wait silently, and
    a run whose every other node had ended never ended itself."""
    path = tmp_path / "deps.toml"
    path.write_text(f"""
[system]
name = "deps"
[system.endpoints]
listen = ["tcp/127.0.0.1:{free_port()}"]

[[node]]
name = "a"
python = "{IOTAS}:Stub"
params = {{ exit_code = 2, exit_after = 0.05 }}
restart = "never"

[[node]]
name = "b"
python = "{IOTAS}:Stub"
after = ["a"]

[[node]]
name = "c"
python = "{IOTAS}:Stub"
after = ["b"]
""")
    run = Launcher(load_system(path), LaunchOptions(live_table=False, log_dir=str(tmp_path / "logs"), until=20,
                                                    node_argv=lambda config: [sys.executable, str(STUB), config]))
    lines: list[str] = []
    run.view.line = lines.append
    started = time.monotonic()
    assert run.run() == 1, lines
    assert time.monotonic() - started < 10, lines
    assert run._stop_reason == "all nodes ended", lines
    assert run.runs["b"].state == run.runs["c"].state == "failed", lines
    assert any(line.startswith("b: ") and "will not start" in line and "a" in line for line in lines), lines
    assert any(line.startswith("c: ") and "will not start" in line for line in lines), lines
