"""Recording format 2 in both ways of running one system file: the CAN ping-pong run in real
time over a CAN tier (`system_can_tier`: udp_multicast in a private network namespace here) and
the same file run in virtual time both state format 2 and both check clean. In real time nothing
models the bus: its logger records the frames it hears in bursts (each at its arrival, no
station); in virtual time the modelled bus records bursts; both are read back frame by frame. Either way each station's frames are
matched against the bus's log and the other station's receipts."""
import sys
from pathlib import Path

import pytest

from pingpong import run_pingpong
from iotad.cli import main
from iotad.recording.bursts import is_burst, wire_frames
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from recorded_systems import check_of_a_real_run  # noqa: E402


def test_a_real_time_run_on_a_can_tier_writes_format_2_and_checks_clean(system_can_tier, tmp_path):
    path = run_pingpong(system_can_tier, tmp_path)
    recording = read_recording(path)
    assert recording.format_version == 2
    logger_bursts = [e for e in recording.trace("can0", derived=False) if is_burst(e)]  # the real bus's log
    assert logger_bursts and sum(len(e["value"]) for e in logger_bursts) == len(wire_frames(recording, "can0"))
    assert all(f["station"] is None for e in logger_bursts for f in e["value"])  # a real bus names no sender
    logged = wire_frames(recording, "can0")
    assert len([f for f in logged if f["id"] == 0x10]) >= 10 and len([f for f in logged if f["id"] == 0x11]) >= 10
    report = check_delivery(recording)
    links = {link.label: link for link in report.links}
    for label in ("can can0: pinger -> (bus)", "can can0: echo -> (bus)", "can can0: pinger -> echo",
                  "can can0: echo -> pinger"):
        assert links[label].problems == 0 and links[label].delivered >= 10, label
    check_of_a_real_run(path)  # nothing but a loaded machine's lateness


def test_the_same_file_run_in_virtual_time_writes_format_2_and_checks_clean(tmp_path, capsys):
    from system_iotas import pingpong_system
    system = tmp_path / "pingpong.toml"
    system.write_text(pingpong_system(0.05, bus='name = "can0"\ninterface = "env"\nstations = ["pinger", "echo"]\n'))
    out = tmp_path / "pingpong.mcap"
    assert main(["run", str(system), "--virtual", "--until", "1", "-o", str(out)]) == 0
    recording = read_recording(out)
    assert recording.format_version == 2
    assert [e for e in recording.trace("can0", derived=False) if is_burst(e)]
    assert len(wire_frames(recording, "can0")) >= 38  # 20 pings and their answers, less what is in flight
    capsys.readouterr()
    assert main(["check", str(out)]) == 0
    assert "every node conforms to its spec, every message was delivered as sent" in capsys.readouterr().out


def test_a_station_that_sends_bursts_in_real_time_puts_each_frame_on_the_bus(system_can_tier, tmp_path):
    """A node's `can_tx_burst` (its frames of one instant in one output) goes on a real bus frame
    by frame, in order: the bus's logger hears each, the echo answers each, and the check reads
    the burst as a `can_tx` per frame and matches them."""
    path = run_pingpong(system_can_tier, tmp_path, pinger="CanBurstPinger")
    recording = read_recording(path)
    own = [e for e in recording.trace("pinger", derived=False) if e["action"] == "can_tx_burst"]
    assert len(own) >= 10 and all(len(e["value"]) == 4 for e in own)
    logged = [f["id"] for f in wire_frames(recording, "can0")]
    assert len([i for i in logged if i in (0x10, 0x11, 0x12, 0x13)]) >= 40
    report = check_delivery(recording)
    links = {link.label: link for link in report.links}
    for label in ("can can0: pinger -> (bus)", "can can0: pinger -> echo"):
        assert links[label].problems == 0 and links[label].delivered >= 40, label
    check_of_a_real_run(path)
