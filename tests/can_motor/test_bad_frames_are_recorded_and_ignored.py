"""Frames the node cannot use are reported on `bad_frame` with the reason and the frame, and change
nothing; the node goes on as if they had not come."""
import math
import struct

import pytest

from motor_bench import (ESTOP, GET_ENCODER_ESTIMATES, HEARTBEAT, SET_INPUT_POS, Bench, can, encoder, heartbeat,
                      setpoints)

BAD = [
    ("WRONG_DLC", can(1, HEARTBEAT, bytes(5))),                        # a heartbeat of 5 bytes
    ("WRONG_DLC", can(2, GET_ENCODER_ESTIMATES, bytes(8), dlc=4)),      # dlc says 4
    ("UNKNOWN_NODE", heartbeat(9)),                                     # node 9 is not in the map
    ("UNKNOWN_COMMAND", can(1, 0x08, bytes(8))),                        # no CAN Simple command 0x08
    ("EXTENDED_ID", can(0, 0, bytes(8), extended=True, ident=0x1ABCDE21)),
    ("UNEXPECTED", can(1, SET_INPUT_POS, bytes(8))),                    # a host command: another master?
    ("UNEXPECTED", can(2, GET_ENCODER_ESTIMATES, rtr=True, dlc=8)),     # someone polls our axis
    ("UNEXPECTED", can(5, ESTOP)),                                      # someone estops it
    ("BAD_VALUE", can(1, GET_ENCODER_ESTIMATES, struct.pack("<ff", math.nan, 0.0))),
    ("BAD_VALUE", can(1, GET_ENCODER_ESTIMATES, struct.pack("<ff", 0.0, math.inf))),
    ("BAD_VALUE", can(1, HEARTBEAT, struct.pack("<IBBBB", 0, 99, 0, 0, 0))),   # Axis_State 99: no such state
    ("BAD_VALUE", can(2, HEARTBEAT, struct.pack("<IBBBB", 0, 8, 77, 0, 0))),   # Procedure_Result 77: none
    ("UNEXPECTED", can(1, HEARTBEAT, bytes([1] * 8), rtr=True)),        # a remote request (its data ignored)
    ("MALFORMED", can(0, 0, bytes(8), ident=0x7FF + 1)),                # 12-bit id in a standard frame
]


def test_each_bad_frame_is_reported_with_its_reason_and_the_frame(bench):
    for k, (_, frame) in enumerate(BAD):
        bench.hear(0.01 + 0.001 * k, frame)
    bench.run(0.1)
    reports = bench.events("bad_frame")
    assert [(e["value"]["reason"], e["value"]["frame"]) for e in reports] == [(r, f) for r, f in BAD]
    assert [e["t"] for e in reports] == [0.01 + 0.001 * k for k in range(len(BAD))]  # at once
    assert not bench.violations()


def test_bad_frames_change_nothing_and_the_node_goes_on(bench):
    bench.hear(0.005, *(encoder(n, 0.0) for n in (1, 2, 5)))
    bench.hear(0.02, *(frame for _, frame in BAD))
    bench.run(0.05)
    motor = bench.motor
    assert [a.phase for a in motor.axes] == ["ARMING"] * 3          # no heartbeat got through
    assert [a.position for a in motor.axes] == [0.0, 0.5, 0.0]      # no estimate got through
    assert not bench.status(event="LOST") and not bench.status(event="ARM_DONE")
    bench.arm_all(0.06)
    bench.post("setpoints", setpoints(3, [0.1, 0.2, 0.3]), t=0.07)
    bench.run(0.07)
    assert len([1 for _, ident, _, _ in bench.sent(since=0.07) if ident & 0x1F == SET_INPUT_POS]) == 3


@pytest.mark.parametrize("garbage", [bytes(range(8)), b"\xff" * 8, b"\x00", b""])
def test_garbage_on_every_id_never_crashes(garbage):
    bench = Bench()
    for ident in range(0x800):
        bench.hear(0.01, can(0, 0, garbage, ident=ident))
    bench.run(0.02)
    assert not bench.violations()
    # whatever it made of them, its own outputs stayed well-formed: every event typed and valid
    assert len(bench.events("bad_frame")) >= 0x800 - 3 * 32
