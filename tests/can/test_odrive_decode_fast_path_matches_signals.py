"""decode reads a message of whole-byte signals with one struct.unpack: for every CAN Simple
message and random data (NaN and infinite floats, negative ints, all bits set) it must give the
values each signal's from_raw gives, bit for bit."""
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
