"""Types, dependency analysis, the real clock, the CLI basics and the README example."""
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from iotad import Array, Bool, Engine, Enum, Float, Input, Int, Iota, Output, RealClock, Struct
from iotad.kernel.dependencies import cells_of
from iotad.kernel.engine import STOP
from iotad.kernel.model import ALL_STATE, ANY, INDEX
from iotad.kernel.types import BadValue

ROOT = Path(__file__).resolve().parents[2]
Point = Struct("point", x=Float, y=Float(-1, 1))


# ---------------------------------------------------------------- types
def test_struct_round_trip_and_errors():
    value = Point.from_plain({"x": 1, "y": 0.5})
    assert value.x == 1.0 and isinstance(value.x, float) and Point.to_plain(value) == {"x": 1.0, "y": 0.5}
    copy = Point.copy(value)
    copy.x = 9
    assert value.x == 1.0, "copies must not share state"
    for plain, message in [({"x": 1}, "missing"), ({"x": 1, "y": 2}, "outside range"),
                           ({"x": 1, "y": 0, "z": 0}, "no field"), ([1, 2], "expected an object"),
                           ({"x": "a", "y": 0}, "expected float"), ({"x": float("nan"), "y": 0}, "NaN")]:
        with pytest.raises(BadValue, match=message):
            Point.from_plain(plain)


def test_enum_array_bool_int_checks_and_schemas():
    Color = Enum("color", "RED", "GREEN")
    assert Color.RED == "RED" and Color.from_plain("GREEN") == "GREEN"
    with pytest.raises(BadValue, match="not a member"):
        Color.from_plain("BLUE")
    with pytest.raises(BadValue, match="expected int"):
        Int.check(True)  # a bool is not an int on a channel
    with pytest.raises(BadValue, match="expected bool"):
        Bool.check(1)
    joints = Array(Float(-3.2, 3.2), 3)
    assert joints.from_plain([0, 1, 2]) == [0.0, 1.0, 2.0]
    with pytest.raises(BadValue, match=r"\[1\]: .*outside range"):
        joints.from_plain([0, 4, 0])
    assert joints.json_schema() == {"type": "array", "items": {"type": "number", "minimum": -3.2, "maximum": 3.2},
                                    "minItems": 3, "maxItems": 3}
    assert Point.json_schema()["required"] == ["x", "y"]


# ---------------------------------------------------------------- dependency analysis
STATE = frozenset({"request", "current", "flag"})


def helper_reader(self, i):
    return self.request[i].status == 1 and self.flag


def test_cells_of_distinguishes_own_element_from_whole_variable():
    assert cells_of(lambda self, i: self.request[i].status == 1 and self.flag, STATE) == \
        {("request", INDEX), ("flag", ANY)}
    assert cells_of(lambda self, i: self.request[self.current].status, STATE) == \
        {("request", ANY), ("current", ANY)}
    assert cells_of(helper_reader, STATE) == {("request", INDEX), ("flag", ANY)}
    assert cells_of(lambda self: self.N > 0, STATE) == frozenset()  # parameters never change


def test_cells_of_is_conservative_when_it_cannot_follow():
    assert cells_of(lambda self, i: self.method(i), STATE) is ALL_STATE
    assert cells_of(lambda self, i: len(vars(self)) > 0, STATE) is ALL_STATE
    assert cells_of(eval("lambda self, i: self.flag"), STATE) is ALL_STATE  # no source to read

    def reassigns(self, i):
        i = 0
        self.request[i].status = 2
    assert cells_of(reassigns, STATE) == {("request", ANY)}


# ---------------------------------------------------------------- real clock
class Echo(Iota):
    inp = Input(Int)
    out = Output(Int)

    def init(self):
        self.pending = None

    @inp.input
    def got(self, x):
        self.pending = x

    @out.action(value=lambda self: self.pending * 2, when=lambda self: self.pending is not None, within=(0, 0.05))
    def sent(self):
        self.pending = None


def test_real_clock_engine_serves_inputs_posted_from_another_thread_and_stops():
    engine = Engine(Echo("echo"), clock=RealClock())
    runner = threading.Thread(target=engine.run, daemon=True)
    runner.start()
    engine.post(None, "inp", 21)
    deadline = time.monotonic() + 5
    while not any(e["kind"] == "output" for e in list(engine.trace)) and time.monotonic() < deadline:
        time.sleep(0.005)
    engine.clock.post(STOP)
    runner.join(5)
    assert not runner.is_alive()
    outputs = [e for e in engine.trace if e["kind"] == "output"]
    assert [e["value"] for e in outputs] == [42]
    assert outputs[0]["t"] >= [e for e in engine.trace if e["kind"] == "input"][0]["t"]


def test_real_clock_shares_an_origin_and_scales_by_time_unit():
    origin = time.time() - 10.0
    assert 9.9 < RealClock(origin=origin).now() < 11
    assert 9900 < RealClock(time_unit=0.001, origin=origin).now() < 11000


# ---------------------------------------------------------------- CLI and README
def test_version_and_help():
    out = subprocess.run([sys.executable, "-m", "iotad", "--version"], capture_output=True, text=True, check=True)
    assert re.fullmatch(r"iotad \d+\.\d+\.\d+\n", out.stdout)
    out = subprocess.run([sys.executable, "-m", "iotad", "--help"], capture_output=True, text=True, check=True)
    assert "COMMAND" in out.stdout and "demo" in out.stdout


def test_readme_example_runs_as_written():
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## Write an IOTA.*?```python\n(.*?)```", text, re.S).group(1)
    out = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, check=True, cwd=ROOT)
    lines = out.stdout.strip().splitlines()
    assert "'t': 1.0" in lines[0] and "'kind': 'input'" in lines[0]
    assert "'t': 1.2" in lines[1] and "'value': 42" in lines[1]


def test_an_int_of_thousands_of_digits_is_a_bad_value_that_says_its_size():
    """Python writes no int of more than 4300 digits as text, so the message cannot show it."""
    with pytest.raises(BadValue, match=r"an integer of about 5001 digits does not fit in 64 bits"):
        Int.check(10 ** 5000)
    with pytest.raises(BadValue, match=r"^-9223372036854775809 does not fit in 64 bits"):
        Int.check(-(2 ** 63) - 1)
