"""Each launcher counts outputs from the nodes' traces for its summary (iotad/launcher/run/tally.py).
The hub counts every node's: its summary is the run's. Another host's launcher counts its own
nodes' only: subscribed to every trace, it had every other host's whole trace stream brought
across its link (vision's camera images, the CAN bus), and over a link slowed to 256 kbit/s that
held the setpoints to arm back by up to 3 s (48 trips of its link watch in 20 s)."""
from iotad.launcher.run.hub import trace_keys_counted
from iotad.launcher.system.system_file import load_system
from namespaces import split_figure2


def test_the_hub_counts_every_nodes_trace_and_another_host_its_own_nodes_only(tmp_path):
    path = tmp_path / "split.toml"
    path.write_text(split_figure2("split", "10.0.0.1", 7600, "a", "b", "10.0.0.2", third=("c", "10.0.0.3")))
    system = load_system(path)
    assert {node.name: node.host for node in system.nodes.values()} == {"scheduler": "c", "vision": "b"}
    assert trace_keys_counted(system, "a") == ["iota/split/**/@trace"]
    assert trace_keys_counted(system, "b") == ["iota/split/vision/@trace"]
    assert trace_keys_counted(system, "c") == ["iota/split/scheduler/@trace"]
    # one machine, no hosts: the launcher is the hub
    assert trace_keys_counted(system, None) == ["iota/split/**/@trace"]
