"""Message types: one definition each, msgpack round trips, JSON Schemas committed and current."""
import json

import pytest
from hypothesis import given, strategies as st

import channels
from channels.schema_gen import SCHEMA_DIR, expected_files
from iotad.node_host import wire
from iotad.kernel.types import BadValue

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


def test_registry_names_are_type_names():
    for name, type in channels.REGISTRY.items():
        assert type.name == name
    assert {"mode", "mdlReq", "ack", "jointSetpoint", "jointState"} <= set(channels.REGISTRY)


def test_schema_files_are_up_to_date():
    """Fails when a type changed without `python -m channels.schema_gen` being run."""
    wanted = expected_files()
    present = {p.name: p.read_text() for p in SCHEMA_DIR.glob("*.json")}
    assert sorted(present) == sorted(wanted), "run: python -m channels.schema_gen"
    for name, text in wanted.items():
        assert present[name] == text, f"{name} is stale; run: python -m channels.schema_gen"


def test_schema_json_is_the_type_schema():
    for name, type in channels.REGISTRY.items():
        schema = json.loads(channels.schema_json(name))
        assert schema.pop("$schema").startswith("https://json-schema.org/")
        assert schema == type.json_schema()


def test_paper_messages_round_trip():
    request = channels.MDL_REQ(control=channels.MODE(w=1.5, k=0.5), epoch=2.0, timeout=3.0, priority=4)
    payload = channels.encode(channels.MDL_REQ, request)
    assert wire.decode(payload) == {"control": {"w": 1.5, "k": 0.5}, "epoch": 2.0, "timeout": 3.0, "priority": 4}
    assert channels.decode(channels.MDL_REQ, payload) == request
    assert channels.decode(channels.ACK, channels.encode(channels.ACK, "COMMIT")) == "COMMIT"


@given(joint=st.integers(0, 31), position=finite, velocity=finite, effort=finite,
       stamp=st.floats(0, 1e9, allow_nan=False))
def test_joint_state_round_trips(joint, position, velocity, effort, stamp):
    state = channels.JOINT_STATE(joint=joint, position=position, velocity=velocity, effort=effort, stamp=stamp)
    assert channels.decode(channels.JOINT_STATE, channels.encode(channels.JOINT_STATE, state)) == state


@given(st.lists(finite, min_size=18, max_size=18))
def test_joint_setpoint_arrays_round_trip(numbers):
    type = channels.JOINT_SETPOINTS
    value = type(position=numbers[:6], velocity_ff=numbers[6:12], torque_ff=numbers[12:])
    assert channels.decode(type, channels.encode(type, value)) == value


def test_array_types_are_shared_per_joint_count():
    assert channels.joint_setpoints(6) is channels.JOINT_SETPOINTS
    assert channels.lookup("jointStates3") is channels.joint_states(3)
    assert channels.lookup("jointStates3").fields["position"].length == 3
    with pytest.raises(KeyError):
        channels.lookup("noSuchType")


def test_decode_rejects_what_does_not_fit():
    with pytest.raises(BadValue):  # wrong length
        channels.decode(channels.JOINT_SETPOINTS, wire.encode({"position": [0.0], "velocity_ff": [0.0],
                                                               "torque_ff": [0.0]}))
    with pytest.raises(BadValue):  # out of range
        channels.decode(channels.JOINT_STATE, wire.encode({"joint": -1, "position": 0.0, "velocity": 0.0,
                                                           "effort": 0.0, "stamp": 0.0}))
    with pytest.raises(wire.WireError):
        channels.decode(channels.MODE, b"\xc1")
    with pytest.raises(BadValue):
        channels.encode(channels.ACK, "MAYBE")
