"""A run spread over hosts records on every host: the hub's `-o split.mcap` becomes `split.arm.mcap`
for host arm, which the hub's `iotad run` hands to the arm's agent with its part (its --force and
split options too); the arm's launcher listens on a port it knows, so that its recorder and nodes
can be told where. No network here: the orders are looked at, not sent."""
from pathlib import Path

import pytest

from namespaces import split_figure2
from iotad.launcher.options import RunOptions
from iotad.launcher.run.run_system import fleet_for
from iotad.launcher.system.system_file import load_system
from iotad.launcher.hosts.host_recording import host_files, host_recording_path, join_command, local_endpoints, pinned


@pytest.mark.parametrize("given, arm", [
    ("recordings/split.mcap", "recordings/split.arm.mcap"),
    ("/data/run.2024.mcap", "/data/run.2024.arm.mcap"),
    ("plain", "plain.arm.mcap"),
])
def test_a_hosts_file_is_the_hubs_with_its_name_before_the_suffix(given, arm):
    assert host_recording_path(given, "arm") == Path(arm)


def test_a_listen_port_0_is_pinned_so_that_the_hosts_recorder_can_be_told_where():
    endpoints = pinned(["tcp/127.0.0.1:0", "tcp/127.0.0.1:7447", "unixsock-stream//tmp/x"])
    port = int(endpoints[0].rpartition(":")[2])
    assert 0 < port < 65536 and endpoints[1:] == ["tcp/127.0.0.1:7447", "unixsock-stream//tmp/x"]
    assert local_endpoints(["tcp/0.0.0.0:7500", "tcp/10.0.0.2:0"]) == ["tcp/127.0.0.1:7500"]  # loopback-ok: test data, the 0.0.0.0 is what is refused


def test_each_agent_is_told_to_record_its_part_beside_the_hubs_recording(tmp_path):
    path = tmp_path / "split.toml"
    path.write_text(split_figure2("split", "127.0.0.1", 7625, "brain", "arm", "127.0.0.1"))
    system = load_system(path)
    options = RunOptions(force=True, max_duration=60.0)
    fleet, host = fleet_for(system, options, None, str(tmp_path / "rec" / "split.mcap"))
    assert host == "brain" and fleet.hosts == ["arm"]
    assert fleet.host_orders == {"arm": RunOptions(host="arm", plain=True, record_to=str(tmp_path / "rec" / "split.arm.mcap"),
                                                   force=True, max_duration=60.0)}
    # without a recording the agents record nothing either
    fleet, _ = fleet_for(system, RunOptions(), None, None)
    assert fleet.host_orders == {"arm": RunOptions(host="arm", plain=True, no_record=True)}


def test_the_join_command_names_every_part_of_the_hubs_and_each_hosts_recording():
    # the hub's recorder restarted once (split_1.mcap); arm's launcher said that its recorder
    # went on in split.arm_1.mcap; base's recorder ran through: its one predicted file
    hosts = {"arm": host_files("rec/split.mcap", "arm", ["rec/split.arm_1.mcap"]),
             "base": host_files("rec/split.mcap", "base", None)}
    assert hosts == {"arm": [Path("rec/split.arm.mcap"), Path("rec/split.arm_1.mcap")],
                     "base": [Path("rec/split.base.mcap")]}
    assert join_command(["rec/split.mcap", "rec/split_1.mcap"], hosts) == (
        "iotad merge rec/split.mcap rec/split_1.mcap rec/split.arm.mcap rec/split.arm_1.mcap rec/split.base.mcap "
        "-o MERGED.mcap")
    # the first file heard again is named once
    assert host_files("split.mcap", "arm", ["split.arm.mcap"]) == [Path("split.arm.mcap")]
