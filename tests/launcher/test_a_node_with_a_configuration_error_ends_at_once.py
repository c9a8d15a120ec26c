"""A node host that exits on a configuration error (exit 2: here its CAN bus cannot open) is not
restarted: the same start would fail the same way. The node ends at once, its reason is said
once (it was restarted five times and said six times), and the run's exit status is 1. A node
that fails otherwise is still restarted by its policy."""
import sys
from pathlib import Path

from iotad.node_host.node_config import CONFIGURATION_ERROR
from iotad.launcher.options import LaunchOptions
from iotad.launcher.run.supervision import Launcher
from iotad.launcher.system.system_file import load_system
from launcher_helpers import IOTAS, free_port
from system_iotas import pingpong_system

STUB = Path(__file__).resolve().parents[1] / "launcher_stub_node.py"
NO_BUS = 'name = "can0"\ninterface = "socketcan"\nchannel = "iotadnone0"\nstations = ["pinger", "echo"]'


def run_system(tmp_path, text: str, **options) -> tuple[Launcher, list[str]]:
    path = tmp_path / "system.toml"
    path.write_text(text)
    lines: list[str] = []
    run = Launcher(load_system(path), LaunchOptions(until=60, live_table=False, log_dir=str(tmp_path / "logs"),
                                                    port=free_port(), **options))
    run.view.line = lines.append
    assert run.run() == 1, lines  # every node ended for good: the run ends by itself, well before --until
    assert run._stop_reason == "all nodes ended", lines
    return run, lines


def test_a_bus_that_cannot_open_ends_its_nodes_without_a_restart(tmp_path):
    """The real node host, on a CAN interface that exists on no machine: exit 2, no restart."""
    run, lines = run_system(tmp_path, pingpong_system(0.01, bus=NO_BUS))
    for name in ("pinger", "echo"):
        node = run.runs[name]
        assert (node.state, node.restarts, node.last_code) == ("failed", 0, CONFIGURATION_ERROR), lines
        said = [line for line in lines if line.startswith(f"{name}: ") and "iotadnone0" in line]
        assert len(said) == 1, lines  # the bus's error, once
        assert "failed for good: exit 2 is a configuration error" in said[0] and "cannot open" in said[0], said
        assert not any(line.startswith(f"{name}: restarted") for line in lines), lines


def test_only_exit_2_ends_a_node_at_once(tmp_path):
    """Exit 3 (an error that a restart may mend) is restarted, exit 2 is not, under one policy."""
    text = f"""[system]
name = "two"
[[node]]
name = "config"
python = "{IOTAS}:Rogue"
params = {{ exit_code = 2, exit_after = 0.0, stderr = "config: no such CAN device" }}
max_restarts = 5
backoff = 0.01
[[node]]
name = "crash"
python = "{IOTAS}:Rogue"
params = {{ exit_code = 3, exit_after = 0.0, stderr = "crash: lost the motor" }}
max_restarts = 2
backoff = 0.01
"""
    run, lines = run_system(tmp_path, text, node_argv=lambda config: [sys.executable, str(STUB), config])
    assert (run.runs["config"].restarts, run.runs["config"].state) == (0, "failed"), lines
    assert sum("config: no such CAN device" in line for line in lines) == 1, lines
    assert (run.runs["crash"].restarts, run.runs["crash"].state) == (2, "failed"), lines
    summary = "\n".join(run.summary())
    assert "config: NEVER LIVE: it failed 1 time(s), last with exit 2" in summary, summary
