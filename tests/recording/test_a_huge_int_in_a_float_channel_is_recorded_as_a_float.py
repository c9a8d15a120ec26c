"""An IOTA's own code may put a Python int of any size in a float channel. msgpack carries ints
of 64 bits at most: a larger one is sent and recorded as the float it stands for, and one past
the largest float is a bad_value, never a recorder that dies with the run."""
from iotad.kernel.api import Internal, Iota, Output
from iotad.kernel.types import Array, Float, Struct
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording

POINT = Struct("point", x=Float, y=Float(0, None))


class Counts(Iota):
    """Sends each of VALUES once, as a float, a struct field and an array item."""
    VALUES = [3, 1 << 70, 1 << 2000]

    plain = Output(Float, switching=0)
    point = Output(POINT, switching=0)
    pair = Output(Array(Float, 2), switching=0)
    next_value = Internal(switching=0)

    def init(self):
        self.k = 0
        self.sent = set()

    def _send(self, channel):
        return self.k < len(self.VALUES) and channel not in self.sent

    @plain.action(value=lambda self: self.VALUES[self.k], when=lambda self: self._send("plain"), after=0.1)
    def sent_plain(self):
        self.sent.add("plain")

    @point.action(value=lambda self: POINT(x=self.VALUES[self.k], y=self.VALUES[self.k]),
                  when=lambda self: self._send("point"), after=0.1)
    def sent_point(self):
        self.sent.add("point")

    @pair.action(value=lambda self: [self.VALUES[self.k], 1], when=lambda self: self._send("pair"), after=0.1)
    def sent_pair(self):
        self.sent.add("pair")

    @next_value.action(when=lambda self: len(self.sent) == 3, after=0.1)
    def moved_on(self):
        self.k += 1
        self.sent = set()


def test_ints_past_64_bits_are_recorded_as_floats_and_past_floats_are_bad_values(tmp_path):
    out = tmp_path / "counts.mcap"
    record_run(Counts("counts"), out, until=5)
    recording = read_recording(out)
    assert recording.complete
    outputs = {}
    for event in recording.trace():
        if event["kind"] == "output":
            outputs.setdefault(event["action"], []).append(event["value"])
    big = float(1 << 70)
    assert outputs["plain"] == [3, big]
    assert outputs["point"] == [{"x": 3, "y": 3}, {"x": big, "y": big}]
    assert outputs["pair"] == [[3, 1], [big, 1]]
    assert all(type(value) is float for value in (outputs["plain"][1], outputs["pair"][1][0]))
    violations = [(v["action"], v["value"]["violation"], v["value"]["message"]) for v in recording.violations()]
    assert sorted(violations) == [
        ("pair", "bad_value", "pair: output value rejected: [0]: an int of 2001 bits is too large for a float"),
        ("plain", "bad_value", "plain: output value rejected: an int of 2001 bits is too large for a float"),
        ("point", "bad_value", "point: output value rejected: point.x: an int of 2001 bits is too large for a float"),
    ]
