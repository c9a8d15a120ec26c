"""On a real CAN bus a frame reaches only the stations whose sockets are open: frames a station
sent before another had started are 'not judged' by the delivery check, never 'lost', and every
frame after the start is delivered (ping-pong over the best tier, the echo started last)."""
import sys
from pathlib import Path

from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_io import read_recording

ROOT = Path(__file__).resolve().parents[2]
IOTAS = ROOT / "tests" / "system_iotas.py"


def test_frames_sent_before_the_echo_started_are_not_judged_and_the_rest_delivered(can_tier, tmp_path):
    system = tmp_path / "pingpong.toml"
    system.write_text(f"""[system]
name = "pingpong"
start_timeout = 60.0  # nodes start slowly in user-mode Linux
[[node]]
name = "pinger"
python = "{IOTAS}:CanPinger"
params = {{ period = 0.05 }}
[[node]]
name = "echo"
python = "{IOTAS}:CanEcho"
after = ["pinger"]
[[can]]
name = "can0"
interface = "{can_tier.interface}"
channel = "{can_tier.channel}"
stations = ["pinger", "echo"]
log = false  # no bus logger: one process less to start on the one vCPU of user-mode Linux
""")
    recording = tmp_path / "pingpong.mcap"
    can_tier.run([sys.executable, "-m", "iotad", "run", str(system), "--until", "6", "--after-live", "--plain", "--port", "0",
                  "-o", str(recording), "--log-dir", str(tmp_path / "logs")], timeout=180, cwd=str(tmp_path)).check()
    report = check_delivery(read_recording(recording))
    link = next(link for link in report.links if link.label == "can can0: pinger -> echo")
    early = [f for f in report.notes if f.code == "not judged" and "before echo's engine started" in f.message]
    assert link.lost == 0 and link.altered == 0, [f.message for f in report.findings if f.code == "lost"][:3]
    assert link.delivered >= 10
    assert len(early) >= 1  # the echo started after the pinger's first frames
