"""`wire.parse_key`: a channel key as (system, path, channel, index), None for anything else; the
answers it remembers (the recording tools parse the same few hundred keys millions of times) are
the ones it computes, for more keys than it remembers too."""
from iotad.node_host import wire


def test_keys_of_every_shape():
    assert wire.parse_key("iota/conveyor/arm_bus/rx/1") == ("conveyor", "arm_bus", "rx", 1)
    assert wire.parse_key("iota/conveyor/motor/@trace") == ("conveyor", "motor", "@trace", None)
    assert wire.parse_key("iota/fig/group/scheduler/ack/0") == ("fig", "group/scheduler", "ack", 0)
    assert wire.parse_key("iota/fig/scheduler/2") == ("fig", "scheduler", "2", None)  # 4 chunks: no index
    assert wire.parse_key("iota/fig/@launcher") is None
    assert wire.parse_key("@recorder/gaps") is None
    assert wire.parse_key("other/fig/a/b") is None


def test_remembered_answers_are_the_computed_ones_past_the_memory_size():
    keys = [f"iota/s{k % 7}/node{k}/ch/{k}" if k % 3 else f"iota/s/n{k}/@trace" for k in range(3 * wire._PARSED_MAX)]
    for _ in range(2):
        for key in keys:
            assert wire.parse_key(key) == wire._parse_key(key)
    assert len(wire._PARSED) <= wire._PARSED_MAX
