"""A host other than iotad's may send an ODrive command with fewer bytes than the DBC gives
(`struct.pack('<I', 8)` for Set_Axis_State) or ask for a message with an empty data frame instead
of a remote one ("a message with RTR=0 and an empty payload can also be used", ODrive's CAN
protocol page). The firmware reads what it has; so do the simulated axes. iotad's own host side
stays strict: what it receives from an axis must be whole."""
import struct

import pytest

from iotad.can import odrive
from iotad.can.frame import Frame
from iotad.can.odrive import AXIS_STATE, MalformedFrame
from sim.odrive_axis import AxisConfig, OdriveAxis

CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]


def test_a_short_set_axis_state_arms_the_axis_and_an_empty_get_error_is_answered():
    axis = OdriveAxis(3, AxisConfig())
    arm = Frame(3 << 5 | 0x07, struct.pack("<I", CLOSED_LOOP))  # 4 bytes, the DBC says 8
    assert axis.handle(odrive.decode(arm, as_axis=True), 0.0) == [] and axis.armed
    [answer] = axis.handle(odrive.decode(Frame(3 << 5 | 0x03, b""), as_axis=True), 0.0)  # Get_Error, no data
    assert odrive.decode(answer).name == "Get_Error" and answer.dlc == 8
    axis.handle(odrive.decode(Frame(3 << 5 | 0x18, b""), as_axis=True), 0.0)  # Clear_Errors with no byte
    assert axis.procedure_result == 0


@pytest.mark.parametrize("frame", [Frame(3 << 5 | 0x07, struct.pack("<I", 8)), Frame(3 << 5 | 0x03, b"")])
def test_the_host_side_still_refuses_a_frame_that_is_not_whole(frame):
    with pytest.raises(MalformedFrame, match="has DLC"):
        odrive.decode(frame)
