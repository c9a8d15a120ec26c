"""The documented hardware-in-the-loop run (`python -m iotad.can.tiers run -- iotad run ...
--after-live -o FILE`) in user-mode Linux, the tier docs/can.md names for machines without CAN:
its recorder must live through the whole run, and the run must exit 0 with one complete file.

It did not: on hostfs, user-mode Linux's root file system, the recorder's bare `touch` of its
ready file left the time unchanged, so the launcher saw no sign of life and killed a healthy
recorder as frozen twice `heartbeat_timeout` after it started, before the system was even
live; the recording went on in `NAME.1.mcap` and the run exited 1. This run lasts longer than
that allowance (startup plus 20 s, against 2 x 8 s), in user-mode Linux itself, whatever tier
the other tests of this folder chose (`system_can_tier` prefers faster ones, where the bug hid).
"""
import sys
from pathlib import Path

import pytest

from iotad.can.tiers import TierBus, TierUnavailable
from iotad.recording.mcap_reader import read_recording
from system_iotas import pingpong_system

pytestmark = pytest.mark.timeout(400)  # user-mode Linux: tens of seconds to start the nodes

HEARTBEAT_TIMEOUT = 8.0  # the recorder's allowance once the system is live: twice this
UNTIL = 20.0             # s after every node is live: past that allowance, whatever the start-up took


@pytest.fixture(scope="module")
def uml():
    try:
        return TierBus("uml")
    except TierUnavailable as exc:
        pytest.skip(f"no user-mode Linux tier: {exc}")


def test_the_recorder_lives_through_a_run_in_user_mode_linux(uml, tmp_path):
    system = tmp_path / "pingpong.toml"
    system.write_text(pingpong_system(
        0.05, system=f"start_timeout = 60.0\nheartbeat_timeout = {HEARTBEAT_TIMEOUT}",
        bus='name = "can0"\ninterface = "env"\nstations = ["pinger", "echo"]\n'))
    recording = tmp_path / "pingpong.mcap"
    run = uml.run([sys.executable, "-m", "iotad", "run", str(system), "--until", str(UNTIL), "--after-live",
                   "--plain", "--port", "0", "-o", str(recording), "--log-dir", str(tmp_path / "logs")],
                  timeout=360, cwd=str(tmp_path))
    assert "recorder: killed" not in run.output and "recorder: restarting" not in run.output, run.output[-4000:]
    assert run.returncode == 0, run.output[-4000:]
    assert f"  recording: {recording}\n" in run.output, run.output[-2000:]
    assert sorted(p.name for p in tmp_path.glob("pingpong*.mcap")) == ["pingpong.mcap"]
    whole = read_recording(recording)
    assert whole.complete, whole.path
    # the nodes' traffic, from the start of the run to its end, in the one file
    for node in ("pinger", "echo"):
        assert any(m.topic.startswith(f"iota/pingpong/{node}/") for m in whole.messages), node
    starts = [m for m in whole.messages if m.topic == "iota/pingpong/@launcher"]
    assert starts, "the launcher's events (node starts) are in the recording"
