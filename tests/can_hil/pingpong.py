"""A ping-pong over a CAN bus in real time: tests/system_iotas.py's CanPinger (a frame every
50 ms, or `period`) and CanEcho (answers each), `iotad run` for 6 s after both are live, recorded."""
import sys
from pathlib import Path

from system_iotas import pingpong_system

# User-mode Linux runs every process on one emulated vCPU: under CI load a node can go seconds
# without a heartbeat, and the default 3 s heartbeat_timeout would kill it as frozen.
SYSTEM = "start_timeout = 60.0\nheartbeat_timeout = 15.0"


def run_pingpong(can_tier, folder: Path, *, echo: str = "", bus: str = "", pinger: str = "CanPinger",
                 period: float = 0.05, system_lines: str = "") -> Path:
    """Runs it in `can_tier` and returns the recording. `echo` adds lines to the echo's
    [[node]], `bus` to the [[can]] table (which says `interface = "env"`: the tier's bus),
    `system_lines` to the [system] table.
    A node the launcher restarted fails the run here: these tests judge one life of each node."""
    system = folder / "pingpong.toml"
    system.write_text(pingpong_system(
        period, system=f"{SYSTEM}\n{system_lines}", echo=echo, pinger=pinger,
        bus='name = "can0"\ninterface = "env"\nstations = ["pinger", "echo"]\n' + bus))
    recording = folder / "pingpong.mcap"
    run = can_tier.run([sys.executable, "-m", "iotad", "run", str(system), "--until", "6", "--after-live", "--plain",
                        "--port", "0", "-o", str(recording), "--log-dir", str(folder / "logs")],
                       timeout=180, cwd=str(folder)).check()
    restarts = [line for line in run.output.splitlines() if "restarted (#" in line or "killing pid" in line]
    assert not restarts, "a node was killed or restarted:\n" + run.output[-3000:]
    return recording
