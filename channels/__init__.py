"""Message types carried on channels, shared by Python IOTAs, ESPRIT specs and the recorder.

One definition per type: `REGISTRY` maps the type's name (as an ESPRIT struct or a recording
names it) to the `iotad.kernel.types` type; `encode`/`decode` are the msgpack codec; `schema_json(name)`
is its JSON Schema, as written in channels/schemas/.
"""
from iotad.kernel.types import Type

from .can import CAN_FRAME
from .codec import decode, encode
from .joints import (JOINT_SETPOINT, JOINT_SETPOINTS, JOINT_STATE, JOINT_STATES, joint_setpoints,
                     joint_states)
from .messages import ACK, MDL_REQ, MODE
from .motor import BAD_FRAME, JOINT_STATUS
from .mdl import TYPES as MDL_TYPES

REGISTRY: dict[str, Type] = {t.name: t for t in (MODE, MDL_REQ, ACK, JOINT_SETPOINT, JOINT_STATE,
                                                 JOINT_SETPOINTS, JOINT_STATES, CAN_FRAME)}
REGISTRY.update({t.name: t for t in (JOINT_STATUS, BAD_FRAME)})  # the CAN motor node (channels/motor.py)
REGISTRY.update({t.name: t for t in MDL_TYPES})  # MDL programs, sensor readings, reports (channels/mdl.py)


def lookup(name: str) -> Type:
    """The type registered as `name`; `jointSetpoints<N>`/`jointStates<N>` for any joint count N."""
    if name in REGISTRY:
        return REGISTRY[name]
    for prefix, factory in (("jointSetpoints", joint_setpoints), ("jointStates", joint_states)):
        if name.startswith(prefix) and name[len(prefix):].isdigit():
            return factory(int(name[len(prefix):]))
    raise KeyError(f"no message type {name!r}; known: {sorted(REGISTRY)}")


# The schema helpers live in `schema_gen` (also a script: `python -m channels.schema_gen`);
# imported on use so that running it as a script does not import it twice.
def schema(name: str) -> dict:
    """The JSON Schema (a dict, with "$schema") of message type `name`."""
    from .schema_gen import schema as make

    return make(name)


def schema_json(name: str) -> str:
    """The JSON Schema of message type `name` as stable JSON text, as in channels/schemas/."""
    from .schema_gen import schema_json as make

    return make(name)


def write_schemas(folder=None):
    """Rewrite channels/schemas/*.json (or `folder`) from REGISTRY; returns the paths."""
    from .schema_gen import SCHEMA_DIR, write_schemas as write

    return write(SCHEMA_DIR if folder is None else folder)


__all__ = ["ACK", "BAD_FRAME", "CAN_FRAME", "JOINT_SETPOINT", "JOINT_SETPOINTS", "JOINT_STATE", "JOINT_STATES", "JOINT_STATUS", "MDL_REQ", "MODE",
           "REGISTRY", "decode", "encode", "joint_setpoints", "joint_states", "lookup", "schema",
           "schema_json", "write_schemas"]
