"""A port is written "node.channel" or "node.channel[k]" everywhere (system files, composites,
recorded systems), and `Port.parse` is the one reader of that syntax: what it refuses, the
system file and a composite refuse with the same words."""
import pytest

from iotad import Composite
from iotad.kernel.compose import flatten
from iotad.kernel.model import SpecError
from iotad.kernel.ports import Port, PortSyntaxError
from iotad.launcher.system.declaration import parse_declaration
from system_iotas import Sink, Source


@pytest.mark.parametrize("text, port", [
    ("vision.req", Port("vision", "req")),
    ("scheduler.req[1]", Port("scheduler", "req", 1)),
    (" arm/wrist.can_tx ", Port("arm/wrist", "can_tx")),
    ("buggy/conscious/wander.out[12]", Port("buggy/conscious/wander", "out", 12)),
])
def test_a_port_reads_back_as_written(text, port):
    assert Port.parse(text) == port
    assert str(port) == text.strip() and Port.parse(str(port)) == port


@pytest.mark.parametrize("text", ["req", "a.b.c", "a.req[x]", "a.req[1", "a b.req", "a.1req", "", 3, None])
def test_what_is_no_port_is_refused(text):
    with pytest.raises(PortSyntaxError, match="is not \"node.channel\" or \"node.channel\\[k\\]\""):
        Port.parse(text)
    assert Port.parsed(text) is None


def test_a_composites_own_channel_has_no_node():
    assert Port.parse("served[2]", node_optional=True) == Port("", "served", 2)
    assert str(Port("", "served", 2)) == "served[2]"


def test_the_system_file_and_a_composite_refuse_the_same_text():
    declared = parse_declaration('[[bind]]\nfrom = "a.b.c"\nto = "sink.inp"\n')
    assert declared.binds[0].ports is None and declared.bindings == []
    with pytest.raises(SpecError, match="bad endpoint 'src.out\\[x\\]'"):
        flatten(Composite("pair", Source("src"), Sink("sink"), bind=[("src.out[x]", "sink.inp")]))
    flat = flatten(Composite("pair", Source("src"), Sink("sink"), bind=[("src.out", "sink.inp")]))
    assert [(str(s), str(t)) for s, t in flat.bindings] == [("pair/src.out", "pair/sink.inp")]
