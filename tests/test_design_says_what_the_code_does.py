"""docs/design.md says what the code does on the points where the two had drifted apart: CAN
below the host, how a node host publishes its `@trace` bursts, which keys `**` misses (the `@`
chunks) and what subscribes to all of a system, and the order at one instant when a whole system
runs in one process. Each claim is read from the page and checked against the code itself."""
import re
from pathlib import Path

from iotad import Input, Int, Iota, Output
from iotad.node_host import wire
from iotad.node_host.host_clock import HostClock
from iotad.node_host.node_config import NodeConfig
from iotad.kernel.clock import VirtualClock
from iotad.kernel.compose import Composite
from iotad.kernel.engine import Engine
from test_layering import LAYERS, imported_modules

ROOT = Path(__file__).resolve().parents[1]
DESIGN = (ROOT / "docs" / "design.md").read_text(encoding="utf-8")


def layer_table() -> dict[str, str]:
    """layer -> its "may import" cell, in the page's order."""
    rows = re.findall(r"^\| (\w+) \| `iotad/\w+/` \| [^|]+ \| ([^|]+) \|$", DESIGN, re.M)
    return {layer: imports.strip() for layer, imports in rows}


def test_the_layer_table_is_the_layering_checks_order_with_can_below_the_host():
    table = layer_table()
    assert list(table) == LAYERS
    assert "can" in table["node_host"] and "node_host" not in table["can"]
    can_imports = {m for path in (ROOT / "iotad" / "can").glob("*.py") for m in imported_modules(path)}
    assert not any(m.startswith(("iotad.node_host", "zenoh")) for m in can_imports)  # it knows nothing of zenoh
    assert "iotad.can.bus" in imported_modules(ROOT / "iotad" / "node_host" / "can_port.py")
    assert "CAN sits below the node host" in DESIGN


def test_the_page_names_every_key_a_system_subscription_needs():
    for key in wire.subscription_keys("<system>"):
        assert f"`{key}`" in DESIGN, key
    assert "`iota/sys/**` does **not** match `iota/sys/a/@trace`" in DESIGN


def test_the_page_gives_the_trace_bursts_period_and_batch_as_the_node_host_has_them():
    period = NodeConfig.__dataclass_fields__["trace_period"].default
    assert f"`trace_period` ({period:g} s by default" in DESIGN
    assert f"or once {HostClock.TRACE_BATCH}\n  are pending" in DESIGN or \
        f"or once {HostClock.TRACE_BATCH} are pending" in DESIGN
    assert "`DATA_LOW` priority" in DESIGN


class B(Iota):
    inp = Input(Int)
    tick = Output(Int)

    def init(self):
        self.got, self.done = 0, False

    @inp.input
    def took(self, value):
        self.got = value

    @tick.action(value=lambda self: self.got, when=lambda self: not self.done, after=1.0)
    def ticked(self):
        self.done = True


class A(Iota):
    out = Output(Int)

    def init(self):
        self.done = False

    @out.action(value=lambda self: 7, when=lambda self: not self.done, after=1.0)
    def sent(self):
        self.done = True


def test_in_one_process_a_due_firing_comes_before_an_input_from_a_node_declared_after_it():
    def story(*parts):
        engine = Engine(Composite("sys", *parts, bind=[("a.out", "b.inp")]), VirtualClock())
        engine.run(2.0)
        return [(e["iota"], e["action"], e["value"]) for e in engine.trace]

    assert story(B("b"), A("a")) == [("sys/b", "tick", 0), ("sys/a", "out", 7), ("sys/b", "inp", 7)]
    assert story(A("a"), B("b")) == [("sys/a", "out", 7), ("sys/b", "inp", 7), ("sys/b", "tick", 7)]
    assert "`b.tick` fires before `a.out` reaches `b.inp`" in DESIGN
