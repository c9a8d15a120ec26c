"""`[[can]] interface = "env"`: the bus comes from IOTAD_CAN_INTERFACE / IOTAD_CAN_CHANNEL (what
`python -m iotad.can.tiers run` sets), so one system file runs on every tier. The node configs
name the environment's bus; without one `iotad run` refuses to start and says how, while
`--check` and `--virtual` need no bus."""
from pathlib import Path

import pytest

from iotad.can.bus import BusUnavailable, open_bus
from iotad.can.frame import Frame
from iotad.cli import main
from iotad.launcher.system.system_file import SystemFileError, load_system

IOTAS = Path(__file__).resolve().parents[1] / "system_iotas.py"
SYSTEM = f"""[system]
name = "pingpong"
[[node]]
name = "pinger"
python = "{IOTAS}:CanPinger"
[[node]]
name = "echo"
python = "{IOTAS}:CanEcho"
[[can]]
name = "can0"
interface = "env"
stations = ["pinger", "echo"]
"""


@pytest.fixture
def system_file(tmp_path, monkeypatch):
    monkeypatch.delenv("IOTAD_CAN_INTERFACE", raising=False)
    monkeypatch.delenv("IOTAD_CAN_CHANNEL", raising=False)
    path = tmp_path / "pingpong.toml"
    path.write_text(SYSTEM)
    return path


def test_node_configs_name_the_environments_bus(system_file, monkeypatch):
    monkeypatch.setenv("IOTAD_CAN_INTERFACE", "udp_multicast")
    monkeypatch.setenv("IOTAD_CAN_CHANNEL", "239.74.163.2")
    system = load_system(system_file)
    for node in ("pinger", "echo", "can0"):  # the stations and the bus logger
        can = system.node_config(node, 0.0, [])["can"]
        assert (can["interface"], can["channel"]) == ("udp_multicast", "239.74.163.2")
    monkeypatch.setenv("IOTAD_CAN_INTERFACE", "socketcan")
    monkeypatch.setenv("IOTAD_CAN_CHANNEL", "can1")
    assert system.node_config("echo", 0.0, [])["can"]["channel"] == "can1"  # read at each node's start


def test_without_a_bus_in_the_environment_run_refuses_and_says_how(system_file, capsys):
    assert main(["run", str(system_file), "--check"]) == 0
    assert main(["run", str(system_file), "--virtual", "--until", "0.05", "-o",
                 str(system_file.with_suffix(".mcap"))]) == 0
    assert main(["run", str(system_file), "--until", "5", "--port", "0", "--no-record", "--plain"]) != 0
    err = capsys.readouterr().err
    assert 'interface = "env" takes the bus from IOTAD_CAN_INTERFACE and IOTAD_CAN_CHANNEL, which are not set' in err
    assert "python -m iotad.can.tiers run" in err


def test_a_channel_beside_env_is_an_error(system_file):
    system_file.write_text(SYSTEM.replace('interface = "env"', 'interface = "env"\nchannel = "vcan0"'))
    with pytest.raises(SystemFileError) as caught:
        load_system(system_file)
    assert any("[[can]] #1" in e and "leave channel out" in e for e in caught.value.errors)


def test_open_bus_env_opens_the_environments_bus(monkeypatch):
    monkeypatch.delenv("IOTAD_CAN_INTERFACE", raising=False)
    with pytest.raises(BusUnavailable, match="IOTAD_CAN_INTERFACE is not set"):
        open_bus("env")
    monkeypatch.setenv("IOTAD_CAN_INTERFACE", "virtual")
    monkeypatch.setenv("IOTAD_CAN_CHANNEL", "env-test")
    with pytest.raises(BusUnavailable, match="give no channel"):
        open_bus("env", "vcan0")
    with open_bus("env") as a, open_bus("virtual", "env-test") as b:
        b.send_frame(Frame(0x10, b"\x07"))
        _, frame = a.recv_frame(timeout=1.0)
        assert (frame.id, frame.data) == (0x10, b"\x07")
