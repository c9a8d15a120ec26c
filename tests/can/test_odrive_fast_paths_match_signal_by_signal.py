"""decode reads a message of whole-byte signals with one struct.unpack, and encode writes one with
one struct.pack: for every CAN Simple message and random data (NaN and infinite floats, negative
ints, all bits set) decode must give the values each signal's from_raw gives, bit for bit; and for
random values (in range, out of range, NaN, infinities, bools, ints, strings, unknown signals, bad
node ids) encode must give the frame, or the EncodeError, that the signal by signal way gives."""
import random
import struct

from iotad.can import odrive
from iotad.can.frame import Frame


def exact(value):
    return ("f", struct.pack("<d", value)) if isinstance(value, float) else (type(value).__name__, value)


def test_every_message_decodes_as_its_signals_say():
    rng = random.Random(9)
    fast = 0
    for spec in odrive.MESSAGES.values():
        fast += spec.cmd_id in odrive._UNPACKERS
        for _ in range(300):
            data = bytes(rng.choice([0, 0xFF, 0x7F, 0x80, rng.randrange(256)]) for _ in range(spec.dlc))
            message = odrive.decode(Frame(odrive.frame_id(5, spec.cmd_id), data))
            bits = int.from_bytes(data, "little")
            expected = {s.name: s.from_raw((bits >> s.start) & ((1 << s.length) - 1)) for s in spec.signals}
            assert list(message.signals) == list(expected), spec.name
            assert {k: exact(v) for k, v in message.signals.items()} == {k: exact(v) for k, v in expected.items()}, \
                (spec.name, data.hex())
    assert fast >= 20  # most messages take the struct path; Heartbeat (a 1-bit flag) and Address do not
    assert odrive.MESSAGES["Heartbeat"].cmd_id not in odrive._UNPACKERS


def test_encoded_setpoints_decode_back():
    frame = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=-0.25, Torque_FF=0.1)
    assert odrive.decode(frame).signals == {"Input_Pos": 1.5, "Vel_FF": -0.25, "Torque_FF": 0.1}


ODD_VALUES = [0, 1, -1, 0.5, -0.0005, 0.0015, 2.5, 1e9, -1e9, 3.5e38, 1e39, float("nan"), float("inf"),
              -float("inf"), True, False, 255, 256, 65535, 65536, -32768, -32769, 32.767, 32.768, (1 << 32) - 1,
              1 << 32, "1", None]


def outcome(fn, *args, **kwargs):
    try:
        frame = fn(*args, **kwargs)
    except odrive.EncodeError as exc:
        return "error", str(exc)
    return "frame", frame.id, frame.data


def test_every_message_encodes_as_its_signals_say():
    rng = random.Random(10)
    for spec in odrive.MESSAGES.values():
        names = list(spec.signal_names)
        for _ in range(400):
            signals = {name: rng.choice([rng.choice(ODD_VALUES), rng.uniform(-40, 40), rng.randrange(-300, 70000)])
                       for name in names if rng.random() < 0.9}
            if rng.random() < 0.02:
                signals["Not_A_Signal"] = 1
            node = rng.choice([5, 5, 5, 63, 64, -1, True])
            assert outcome(odrive.encode, node, spec.name, **signals) == \
                outcome(odrive.encode_by_signals, node, spec.name, **signals), (spec.name, node, signals)
    assert len(odrive._PACKERS) >= 20
    frame = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=-0.25, Torque_FF=0.1)
    assert frame.data == struct.pack("<fhh", 1.5, -250, 100)
