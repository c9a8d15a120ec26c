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
