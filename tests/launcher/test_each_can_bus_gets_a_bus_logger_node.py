"""Each `[[can]]` bus of a system file gets a bus logger in real time: an implicit node named
after the bus (iotad.can.frame_log.BusLogger) whose node host opens the bus listen-only, that
access control lets publish its log, and that `log = false` leaves out. `iotad run --virtual`
leaves it out too: there the bus model logs."""
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.launcher.access.access_policy import derive
from iotad.launcher.system.bus_logger import LOGGER_REF, is_bus_logger
from iotad.launcher.system.in_process import compose
from iotad.launcher.system.system_file import SystemFileError, load_system
from iotad.recording.mcap_reader import read_recording
from system_iotas import PINGPONG_BUS, pingpong_system

SYSTEM = pingpong_system(10, system="time_unit = 0.001", bus=PINGPONG_BUS + "\nbitrate = 500000")


def write(tmp_path: Path, extra: str = "") -> Path:
    path = tmp_path / "pingpong.toml"
    path.write_text(SYSTEM + extra)
    return path


def test_the_logger_is_a_node_named_after_the_bus_that_opens_it_listen_only(tmp_path):
    system = load_system(write(tmp_path))
    assert list(system.nodes) == ["pinger", "echo", "can0"]
    logger = system.nodes["can0"]
    assert is_bus_logger(system, "can0") and not is_bus_logger(system, "echo")
    assert logger.source == {"kind": "python", "ref": LOGGER_REF}
    assert logger.params == {"bitrate": 500_000, "lag": 100.0, "batch": 5.0}  # 0.1 s, 5 ms in the system's ms
    assert (logger.restart, logger.required) == ("on-failure", False)
    assert {c.name: c.direction for c in logger.channels.values()} == {
        "can_rx": "input", "can_rx_burst": "input", "frames": "output", "burst": "output"}
    config = system.node_config("can0", 0.0, ["tcp/127.0.0.1:7447"])
    assert config["can"] == {"bus": "can0", "interface": "socketcan", "channel": "vcan0", "bitrate": 500_000,
                             "options": {}, "listen_only": True}
    assert "listen_only" not in system.node_config("pinger", 0.0, [])["can"]  # a station sends
    grant = next(g for g in derive(system).grants if g.user.endswith("can0"))
    assert "iota/pingpong/can0/burst" in grant.publish  # its log, in bursts (recording format 2)


def test_log_false_runs_no_logger_and_a_bad_log_value_is_named(tmp_path):
    path = write(tmp_path, "log = false\n")
    assert list(load_system(path).nodes) == ["pinger", "echo"]
    write(tmp_path, 'log = "yes"\n')
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    assert any("[[can]] #1" in e and "log must be true or false" in e for e in caught.value.errors)


def test_a_virtual_run_has_the_bus_model_and_no_logger_node(tmp_path):
    system = load_system(write(tmp_path))
    root = compose(system)
    assert sorted(root.components) == ["can0", "echo", "pinger"]
    assert type(root.components["can0"]).__name__ == "BurstCanBus"  # recording format 2
    assert type(compose(system, 1).components["can0"]).__name__ == "CanBus"  # format 1
    out = tmp_path / "v.mcap"
    assert main(["run", str(tmp_path / "pingpong.toml"), "--virtual", "--until", "0.05", "-o", str(out)]) == 0
    records = [m.value for m in read_recording(out).messages if m.topic == "iota/pingpong/can0/frames"]
    assert len(records) >= 8 and all(r["station"] in (0, 1) for r in records)
