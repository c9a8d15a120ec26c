"""An interpreter for 7 joints is a class made at run time (`MdlInterpreter7`); a recording names
it, and `iotad check` / `iotad replay` rebuild it by that name from the stored module source."""
import pytest

from iotad.esprit.stored_spec import build_node, spec_record
from nodes.mdl_interp import interpreter


def test_a_seven_joint_interpreter_is_rebuilt_from_its_recorded_spec():
    made = interpreter.interpreter_class(7)("interp", joints=[f"j{k}" for k in range(7)], lower=[-1.0] * 7,
                                            upper=[1.0] * 7, max_velocity=[1.0] * 7)
    record = spec_record(made, "interp")
    assert record["source"]["ref"].endswith("interpreter.py:MdlInterpreter7")
    rebuilt = build_node(record)
    assert type(rebuilt).__name__ == "MdlInterpreter7" and type(rebuilt).JOINTS == 7
    assert rebuilt.iota_spec.channels["setpoints"].type.name == made.iota_spec.channels["setpoints"].type.name


def test_names_that_are_no_interpreter_class_stay_errors():
    assert interpreter.MdlInterpreter5 is interpreter.interpreter_class(5)
    with pytest.raises(AttributeError):
        interpreter.MdlInterpreter0  # noqa: B018
    with pytest.raises(AttributeError):
        interpreter.NoSuchThing  # noqa: B018
