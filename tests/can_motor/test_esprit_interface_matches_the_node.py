"""nodes/can_motor/can_motor.iota says the node's interface in ESPRIT: the same external channels,
directions, sizes, switching times and value types (by JSON Schema) as the Python IOTA, and the
same parameters where ESPRIT can say them. (`can_tx_burst` and `can_rx_burst`, lists of frames, are
the channels ESPRIT has no type for: the Python node's alone.)"""
from pathlib import Path

from iotad.esprit import load_iota
from iotad.kernel.model import param_values
from nodes.can_motor import CanMotor

SPEC = Path(__file__).resolve().parents[2] / "nodes" / "can_motor" / "can_motor.iota"
LISTS = ("can_tx_burst", "can_rx_burst")  # lists of frames: no ESPRIT type says them
SIX = [{"name": f"joint{k}", "node_id": k} for k in range(1, 7)]


def interface(iota):
    spec, params = iota.iota_spec, param_values(iota)
    return {name: (ch.direction, spec.size_of(ch, params), spec.switching_of(ch, params),
                   None if ch.type is None else ch.type.json_schema())
            for name, ch in spec.channels.items() if ch.external and name not in LISTS}


def test_the_esprit_interface_is_the_python_node_for_six_joints():
    esprit, python = load_iota(str(SPEC), name="motor"), CanMotor("motor", joints=SIX)
    assert interface(esprit) == interface(python)
    assert {name: ch.type.name for name, ch in esprit.iota_spec.channels.items() if ch.type is not None} == \
        {name: ch.type.name for name, ch in python.iota_spec.channels.items()
         if ch.external and ch.type is not None and name not in LISTS}


def test_the_esprit_parameters_are_the_python_defaults():
    esprit = param_values(load_iota(str(SPEC), name="motor"))
    python = param_values(CanMotor("motor", joints=SIX))
    assert set(python) - set(esprit) == {"joints", "polls"}  # tables: ESPRIT has no such type
    assert {k: python[k] for k in esprit} == esprit
