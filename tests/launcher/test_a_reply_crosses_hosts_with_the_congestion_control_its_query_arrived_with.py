"""zenoh (1.10) sends a query's reply with the QoS its query arrived with, so that a query the hub,
a host's router or an open run's node sends to another host with DROP (zenoh's `qos/network`
overwrite, which takes only puts, deletes and queries) is answered with DROP as well: a reply never
waits on a full queue toward a host that was cut off. Declarations go at the control priority with
BLOCK whatever the overwrite (docs/hosts.md, section 8). Read from zenoh's own trace log of the
replying process (bench/wire_congestion.py): if a zenoh release changes either, this says so."""
import importlib.util

from launcher_helpers import ROOT


def wire_congestion():
    spec = importlib.util.spec_from_file_location("wire_congestion", ROOT / "bench" / "wire_congestion.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_reply_takes_its_querys_congestion_control_and_a_declaration_keeps_block():
    bench = wire_congestion()
    plain, overwritten = bench.wire_qos(False), bench.wire_qos(True)
    assert plain["Response"] == plain["ResponseFinal"] == {("Data", "Block")}, plain
    assert overwritten["Response"] == overwritten["ResponseFinal"] == {("Data", "Drop")}, overwritten
    assert plain["Declare"] == overwritten["Declare"] == {("Control", "Block")}, (plain, overwritten)
