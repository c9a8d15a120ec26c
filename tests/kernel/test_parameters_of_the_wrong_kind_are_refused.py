"""A Python IOTA's parameter given a value its default's kind rules out (text or NaN for a number,
anything but true/false for a flag) is refused when the IOTA is made, naming the parameter,
so `iotad run --check` says it before anything runs; other kinds stay the IOTA's business."""
import math

import pytest

from iotad.kernel.api import Iota, Output, Param
from iotad.kernel.model import SpecError


class Arm(Iota):
    speed = Param(1.5)
    count = Param(3)
    verbose = Param(False)
    limits = Param([])
    label = Param("arm")
    anything = Param(None)
    out = Output()


@pytest.mark.parametrize("params, said", [
    ({"speed": "fast"}, "parameter speed: expected a number (its default is 1.5), got 'fast'"),
    ({"count": True}, "parameter count: expected a number (its default is 3), got True"),
    ({"speed": math.nan}, "parameter speed: expected a number (its default is 1.5), got NaN"),
    ({"verbose": 1}, "parameter verbose: expected true or false (its default is False), got 1"),
    ({"verbose": "yes"}, "parameter verbose: expected true or false (its default is False), got 'yes'"),
])
def test_a_value_of_the_wrong_kind_is_refused(params, said):
    with pytest.raises(SpecError) as caught:
        Arm("arm", **params)
    assert said in str(caught.value)


@pytest.mark.parametrize("params", [
    {"speed": 2}, {"count": 2.5}, {"speed": math.inf}, {"speed": [1.0, 2.0]},  # one per joint
    {"verbose": True}, {"limits": {"a": 1}}, {"label": 7}, {"anything": "x"}, {"speed": None},
])
def test_other_kinds_are_the_iotas_business(params):
    arm = Arm("arm", **params)
    for key, value in params.items():
        assert getattr(arm, key) == value


def test_run_check_names_the_node_and_the_parameter(tmp_path, capsys):
    from pathlib import Path

    from iotad.cli import main
    root = Path(__file__).resolve().parents[2]
    system = tmp_path / "bad.toml"
    system.write_text((root / "examples" / "figure2.toml").read_text()
                      .replace('"requesters.py:Requester"', f'"{root}/examples/requesters.py:Requester"')
                      .replace('"../nodes/', f'"{root}/nodes/')
                      .replace("priority = 1,", 'priority = "high",', 1))
    assert main(["run", "--check", str(system)]) == 2
    err = capsys.readouterr().err
    assert '(name="vision"): cannot instantiate its IOTA: Requester: parameter priority: expected a number ' \
           "(its default is 1), got 'high'" in err
