"""A system file is declared (nodes, bindings as port pairs, externals, buses, hosts) without any
of its nodes' code: parsing imports no node, simulator or example module and compiles no ESPRIT.
Checking (building each IOTA) is a separate step, so the recorder, the delivery check and the
plots can read a system file, or a recording's copy of one, at once and without robot code."""
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _sweep_file(path: Path) -> bool:
    """A sweep file (docs/sweeps.md) names a system file in its one [sweep] table: it is none."""
    data = tomllib.loads(path.read_text())
    return set(data) == {"sweep"} and "system" in data["sweep"]


EXAMPLES = sorted(path for path in (ROOT / "examples").glob("**/*.toml") if not _sweep_file(path))

PROBE = r"""
import json, sys
from iotad.launcher.system.declaration import read_declaration, parse_declaration
declaration = read_declaration(sys.argv[1])
copy = parse_declaration(open(sys.argv[1]).read())  # as a recording keeps it: no folder
loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("nodes", "sim", "examples")
                or m.startswith("iotad.esprit") or m.startswith("iotad.can.frame_log"))
print(json.dumps({
    "errors": list(declaration.errors), "copy_errors": list(copy.errors),
    "nodes": list(declaration.nodes), "copy_nodes": list(copy.nodes),
    "bindings": [[str(s), str(t)] for s, t in declaration.bindings],
    "binds": len(declaration.binds), "external": [str(p) for p in declaration.external],
    "buses": {name: list(bus.stations) for name, bus in declaration.buses.items()},
    "loaded": loaded}))
"""


def declared(path: Path) -> dict:
    # a process of its own: this test's process has imported node code already
    done = subprocess.run([sys.executable, "-c", PROBE, str(path)], capture_output=True, text=True, timeout=60,
                          cwd=ROOT)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_there_are_example_system_files():
    assert len(EXAMPLES) >= 5, EXAMPLES


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: str(p.relative_to(ROOT / "examples")))
def test_an_example_is_declared_without_its_nodes_code(path):
    found = declared(path)
    assert found["errors"] == [] and found["copy_errors"] == []
    assert found["loaded"] == []  # no nodes.*, sim.*, examples.*, no ESPRIT compiler, no bus logger class
    assert found["nodes"] and found["nodes"] == found["copy_nodes"]
    # every [[bind]] is a pair of ports, and every port names a declared node
    assert len(found["bindings"]) == found["binds"]
    for pair in found["bindings"]:
        for port in pair:
            assert port.split(".")[0] in found["nodes"], port
    for bus, stations in found["buses"].items():
        assert bus in found["nodes"] or not stations  # its logger node, added by the parse
        assert set(stations) <= set(found["nodes"])


def test_the_declaration_is_what_the_checked_system_is_built_from():
    from iotad.launcher.system.system_file import load_system

    system = load_system(ROOT / "examples" / "figure2.toml")
    declaration = system.declaration
    assert list(system.nodes) == list(declaration.nodes)
    concrete = {(b.source, b.target) for b in system.bindings}
    # a family bound whole declares one pair and checks into one pair per member
    for source, target in declaration.bindings:
        assert (source, target) in concrete or any(s.node == source.node and s.channel == source.channel
                                                   and t.node == target.node for s, t in concrete)
    with pytest.raises(AttributeError):
        declaration.nodes["scheduler"].params = {}  # frozen: checking cannot change what was declared
