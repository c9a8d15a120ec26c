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


def test_a_bus_log_record_from_a_record_is_the_one_from_its_frame():
    """bus_frame takes a CAN_FRAME record the bus's input checked without building a Frame; the
    log record must be the one the Frame gives: data past the DLC (and a remote frame's) zeroed,
    direction and message by id, RTR and DLC, a frame no controller could send still refused."""
    from iotad.can.frame import CAN_FRAME, FrameError
    from iotad.can.frame_log import bus_frame
    from iotad.kernel.types import to_plain
    import pytest

    rng = random.Random(11)
    for _ in range(5000):
        id, rtr, dlc = rng.randrange(0x800), rng.random() < 0.2, rng.randrange(9)
        record = CAN_FRAME.record(id=id, extended=False, rtr=rtr, dlc=dlc,
                                  data=[rng.randrange(256) for _ in range(8)])  # garbage past the DLC
        for _ in range(2):  # the first may fill classify's memory, the second reads it
            got = to_plain(bus_frame(record, 1, 1e-4))
            frame = Frame.from_value(record)
            assert got == to_plain(bus_frame(frame.to_value(), 1, 1e-4))
            assert got["data"] == list(frame.data) + [0] * (8 - len(frame.data))
    bad = CAN_FRAME.record(id=0x800, extended=False, rtr=False, dlc=1, data=[1] + [0] * 7)
    with pytest.raises(FrameError, match="does not fit a 11-bit standard id"):
        bus_frame(bad, 0, 1e-4)
