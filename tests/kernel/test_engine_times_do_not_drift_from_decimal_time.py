"""Window bounds and switching times are summed in floats, and float sums drift (0.1 + 0.2 >
0.3). The engine rounds the times it computes to 1e-9 of a time unit, as recordings hold them,
so that decimal times mean what they say."""
from iotad import Engine, Float, Input, Int, Iota, Output, VirtualClock


class Switched(Iota):
    inp = Input(Int, switching=0.2)
    out = Output(Int, switching=0.1)

    def init(self):
        self.seen, self.sent = 0, 0

    @inp.input
    def got(self, x):
        self.seen = x

    @out.action(value=lambda self: self.seen, when=lambda self: self.sent < 9)
    def sent_out(self):
        self.sent += 1


def run(inputs):
    engine = Engine(Switched("s"), VirtualClock())
    for t, value in inputs:
        engine.post("s", "inp", value, t=t)
    engine.run(1.0)
    return engine


def test_an_input_exactly_its_switching_time_after_the_last_is_accepted():
    engine = run([(0.1, 1), (0.3, 2)])  # 0.1 + 0.2 is 0.30000000000000004 in floats
    assert [(e["t"], e["value"]) for e in engine.trace if e["kind"] == "input"] == [(0.1, 1), (0.3, 2)]
    assert not [e for e in engine.trace if e["kind"] == "violation"]


def test_repeated_switching_times_land_on_decimal_times_and_inputs_come_first():
    engine = run([(0.8, 7)])
    events = [(e["t"], e["kind"], e["value"]) for e in engine.trace if e["kind"] in ("input", "output")]
    assert [t for t, kind, _ in events if kind == "output"] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]
    # eight steps of 0.1 end at 0.8 exactly, where the input is: it comes first, and is sent
    assert events[-2:] == [(0.8, "input", 7), (0.8, "output", 7)]


class FarOff(Iota):
    """A window whose bounds are in range but past what the grid can scale (1e300 * 1e9 = inf)."""
    delay = Input(Float(0, None), switching=0)
    out = Output(Int, switching=1e300)

    def init(self):
        self.after = 0.5

    @delay.input
    def got(self, x):
        self.after = x

    @out.action(value=lambda self: 1, within=(lambda self: self.after, lambda self: 1e300))
    def sent_out(self):
        pass


def test_times_too_far_for_the_grid_are_never_reached_and_break_nothing():
    engine = Engine(FarOff("f"), VirtualClock())
    engine.post("f", "delay", 1e300, t=0.2)
    engine.run(10.0)
    # one output at 0.5; its switching time (1e300) puts the next out of reach, and the input of
    # 1e300 is taken as any other value: no crash, no violation
    assert [(e["t"], e["kind"]) for e in engine.trace] == [(0.2, "input"), (0.5, "output")]
