"""frame_bits counts a frame's bits on integers (table CRC, stuff bits run by run) and remembers
its answers; the reference is the bit list of stuffed_region, its crc15 and stuff_bit_count.
Both must agree on every frame, stuffing mode and odd input."""
import random

import pytest

from iotad.can import bit_timing as bt


def reference(id, extended, rtr, data, stuffing, dlc):
    region = bt.stuffed_region(id, extended, rtr, data, dlc)
    stuff = {"exact": bt.stuff_bit_count(region), "worst": (len(region) - 1) // 4, "none": 0}[stuffing]
    return len(region) + stuff + bt.UNSTUFFED_TAIL + bt.INTERMISSION


def frames(seed, count):
    rng = random.Random(seed)
    for _ in range(count):
        extended = rng.random() < 0.3
        id = rng.randrange(1 << (30 if extended else 12))  # some beyond the id's width
        rtr = rng.random() < 0.2
        dlc = rng.randrange(9)
        # runs of equal bits are where stuffing happens: many 0x00 and 0xFF bytes
        data = bytes(dlc) if rtr else bytes(rng.choice([0, 255, rng.randrange(256)]) for _ in range(dlc))
        yield id, extended, rtr, data, rng.choice([None, dlc])


@pytest.mark.parametrize("stuffing", ["exact", "worst", "none"])
def test_random_frames_agree_with_the_bit_by_bit_count(stuffing):
    for id, extended, rtr, data, dlc in frames(7, 4000):
        expected = reference(id, extended, rtr, data, stuffing, dlc)
        assert bt.frame_bits(id, extended, rtr, data, stuffing, dlc) == expected, (id, extended, rtr, data, dlc)
        assert bt.frame_bits(id, extended, rtr, data, stuffing, dlc) == expected  # from the memo now


def test_long_runs_of_equal_bits_agree():
    for byte in (0x00, 0xFF, 0x0F, 0xF0, 0x1F, 0xE0, 0x7C):
        for dlc in range(9):
            for id in (0, 0x7FF, 0x3E0, 0x01F, 0x400):
                data = bytes([byte] * dlc)
                assert bt.frame_bits(id, False, False, data) == reference(id, False, False, data, "exact", None)
                assert bt.frame_bits(id << 18, True, False, data) == reference(id << 18, True, False, data, "exact", None)


def test_data_as_a_list_is_counted_too_and_not_remembered():
    data = [1, 2, 3, 0, 0, 0, 0, 0]
    assert bt.frame_bits(0x21, False, False, data) == reference(0x21, False, False, bytes(data), "exact", None)


def test_a_bad_stuffing_mode_is_still_an_error():
    with pytest.raises(ValueError, match="stuffing must be"):
        bt.frame_bits(0x21, False, False, b"\x01", "sometimes")
