"""A ping-pong over a CAN bus in real time: tests/system_iotas.py's CanPinger (a frame every
50 ms) and CanEcho (answers each), `iotad run` for 6 s after both are live, recorded."""
import sys
from pathlib import Path

from system_iotas import pingpong_system


def run_pingpong(can_tier, folder: Path, *, echo: str = "", bus: str = "") -> Path:
    """Runs it in `can_tier` and returns the recording. `echo` adds lines to the echo's
    [[node]], `bus` to the [[can]] table (which says `interface = "env"`: the tier's bus)."""
    system = folder / "pingpong.toml"
    system.write_text(pingpong_system(
        0.05, system="start_timeout = 60.0  # nodes start slowly in user-mode Linux", echo=echo,
        bus='name = "can0"\ninterface = "env"\nstations = ["pinger", "echo"]\n' + bus))
    recording = folder / "pingpong.mcap"
    can_tier.run([sys.executable, "-m", "iotad", "run", str(system), "--until", "6", "--after-live", "--plain",
                  "--port", "0", "-o", str(recording), "--log-dir", str(folder / "logs")],
                 timeout=180, cwd=str(folder)).check()
    return recording
