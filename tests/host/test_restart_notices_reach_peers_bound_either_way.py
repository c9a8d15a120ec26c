"""Which peers' restarts a node host tells its IOTA about (iotad/node_host/peer_restart.py): nodes
bound to its inputs and nodes bound to read its outputs, each with the channels it is bound
through, as the launcher writes them into the node's config (`inputs` and `readers`)."""
import json
from pathlib import Path

import pytest

from iotad.node_host.node_config import ConfigError, parse
from iotad.node_host.peer_restart import notice_values, peers_of
from iotad.kernel.types import Enum
from iotad.launcher.system.system_file import load_system

ROOT = Path(__file__).resolve().parents[2]


def test_the_launcher_writes_who_reads_each_output():
    system = load_system(ROOT / "examples" / "figure2.toml")
    config = system.node_config("scheduler", origin=0.0, hub=["tcp/127.0.0.1:7447"])
    assert config["readers"] == {"ack/0": ["vision"], "ack/1": ["manipulation"]}
    assert config["inputs"] == {"req/0": ["iota/figure2/vision/req"], "req/1": ["iota/figure2/manipulation/req"]}
    assert system.node_config("vision", origin=0.0, hub=[])["readers"] == {"req": ["scheduler"]}


def test_peers_are_the_nodes_bound_either_way_with_the_channels_that_bind_them():
    conveyor = load_system(ROOT / "examples" / "conveyor.toml")
    config = parse(json.dumps(conveyor.node_config("scheduler", origin=0.0, hub=[])))
    peers = peers_of(config.system, config.path, config.inputs, config.readers)
    assert peers == {"vision": ["req", "ack"], "manipulation": ["req", "ack"], "interpreter": ["mdl_command"]}
    # the resume scheduler's enum has one member: only the interpreter's restart is a notice
    peer = Enum("peer", "mdl_command")
    assert {name: notice_values(peer, channels) for name, channels in peers.items()} == {
        "vision": [], "manipulation": [], "interpreter": ["mdl_command"]}
    # a notice without a value: one per restart of any peer
    assert notice_values(None, peers["vision"]) == [None]


def test_a_node_is_never_its_own_peer():
    assert peers_of("s", "a", {"inp": ["iota/s/a/out", "iota/other/b/out"]}, {"out": ["a", "c"]}) == {"c": ["out"]}


@pytest.mark.parametrize("readers", [["b"], {"out": "b"}, {"out": [1]}])
def test_a_malformed_readers_entry_is_one_clear_config_error(readers):
    text = json.dumps({"system": "s", "path": "a", "source": {"kind": "python", "ref": "x.py:X"}, "readers": readers})
    with pytest.raises(ConfigError, match='readers must map "channel" or "channel/index" to a list of node paths'):
        parse(text)
