"""The launcher turns a node's link watch on where a partition could strand it: a node whose IOTA
has a `link_timeout` parameter (the CAN motor node) gets `[system] link_timeout` (0.06 s unless
the file says) when one of its inputs is bound from a node on another host; on one host, with the
parameter set in the file, or with `link_timeout = 0`, its params are the file's."""
import pytest

from iotad.launcher.system.system_file import SystemFileError, load_system

JOINTS = "joints = [{ name = \"j\", node_id = 1 }]"


def system(tmp_path, motor_host="arm", source_host="brain", system_extra="", motor_params=""):
    text = f"""
[system]
name = "watch"
time_unit = 1.0
external = ["source.mdl_command", "source.mode_command", "source.sensor[0]", "source.sensor[1]", "source.sensor[2]",
            "motor.can_rx", "motor.estop"]
{system_extra}
[hosts.brain]
[hosts.arm]

[[node]]
name = "source"
host = "{source_host}"
python = "nodes.mdl_interp:mdl_interpreter"
params = {{ joints = ["j"], lower = [-1.0], upper = [1.0] }}

[[node]]
name = "motor"
host = "{motor_host}"
python = "nodes.can_motor:CanMotor"
params = {{ {JOINTS}{motor_params} }}

[[bind]]
from = "source.setpoints"
to = "motor.setpoints"
[[bind]]
from = "motor.joint_states"
to = "source.joint_states"
"""
    path = tmp_path / "watch.toml"
    path.write_text(text)
    loaded = load_system(path)
    return {name: loaded.node_config(name, 0.0, ["tcp/127.0.0.1:7447"])["params"] for name in ("source", "motor")}


def test_across_hosts_the_motor_node_gets_the_systems_link_timeout(tmp_path):
    params = system(tmp_path)
    assert params["motor"]["link_timeout"] == 0.06
    assert "link_timeout" not in params["source"]  # its IOTA has no such parameter


def test_on_one_host_set_in_the_file_or_switched_off_it_is_the_files(tmp_path):
    assert "link_timeout" not in system(tmp_path, motor_host="brain")["motor"]
    assert system(tmp_path, motor_params=", link_timeout = 0.2")["motor"]["link_timeout"] == 0.2
    assert "link_timeout" not in system(tmp_path, system_extra="link_timeout = 0")["motor"]
    assert system(tmp_path, system_extra="link_timeout = 0.1")["motor"]["link_timeout"] == 0.1


def test_a_bad_link_timeout_is_a_clear_error(tmp_path):
    with pytest.raises(SystemFileError, match=r"link_timeout.*seconds >= 0 \(0: off\)"):
        system(tmp_path, system_extra="link_timeout = -1")
