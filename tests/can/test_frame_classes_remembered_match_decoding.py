"""classify remembers a standard frame's (direction, message) by id, RTR and DLC: every such key,
with random data, must give what decoding the frame itself gives."""
import random

from iotad.can.frame import Frame
from iotad.can.frame_log import _classify, classify


def test_every_standard_id_rtr_and_dlc_classifies_as_decoding_does():
    rng = random.Random(3)
    for id in range(0x800):
        for rtr in (False, True):
            for dlc in range(9):
                for _ in range(2):  # the first fills the memory, the second reads it
                    data = bytes(dlc) if rtr else bytes(rng.randrange(256) for _ in range(dlc))
                    frame = Frame(id, data, rtr=rtr)
                    assert classify(frame) == _classify(frame), frame


def test_extended_frames_are_not_odrive():
    assert classify(Frame(0x1234567, b"\x01", extended=True)) == ("NOT_ODRIVE", "UNKNOWN")


def test_frame_from_a_record_is_the_frame_from_its_plain_dict():
    """from_value reads a CAN_FRAME record in one go; its plain dict takes the general path."""
    from iotad.can.frame import CAN_FRAME, FrameError
    rng = random.Random(5)
    for _ in range(3000):
        fields = {"id": rng.choice([0x21, 0x7FF, 0x800, 0x1FFFFFFF, -1, None, 3.0]),
                  "extended": rng.choice([False, True, None, 0]), "rtr": rng.choice([False, True, 1]),
                  "dlc": rng.choice([0, 3, 8, 9, -1, True, None, 2.0]),
                  "data": rng.choice([[1, 2, 3, 0, 0, 0, 0, 0], [0] * 8, [1] * 7, (1,) * 8, None, [300] * 8])}
        record = CAN_FRAME.record(**fields)
        outcomes = []
        for value in (record, dict(fields)):
            try:
                outcomes.append(Frame.from_value(value))
            except (FrameError, ValueError, TypeError) as exc:  # bytes([300]) is a ValueError on both paths
                message = str(exc).replace(repr(record), "VALUE").replace(repr(dict(fields)), "VALUE")
                outcomes.append((type(exc).__name__, message))
        assert outcomes[0] == outcomes[1], fields
