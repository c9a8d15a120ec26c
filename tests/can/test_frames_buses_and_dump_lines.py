"""Frames convert losslessly between Frame, the canFrame channel value and python-can messages;
open_bus explains what cannot work here; the candump-like lines name ODrive messages."""
import can
import pytest
from hypothesis import given, strategies as st

import channels
from channels.can import CAN_FRAME
from iotad.can import odrive
from iotad.can.bus import BusUnavailable, open_bus, open_env_bus, real_interfaces
from iotad.can.dump import format_event, format_frame, frame_fields
from iotad.can.frame import Frame, FrameError


@st.composite
def frames(draw):
    extended = draw(st.booleans())
    ident = draw(st.integers(0, 0x1FFFFFFF if extended else 0x7FF))
    if draw(st.booleans()):
        return Frame.remote(ident, draw(st.integers(0, 8)), extended=extended)
    return Frame(ident, draw(st.binary(max_size=8)), extended=extended)


@given(frames())
def test_a_frame_survives_every_conversion(frame):
    value = frame.to_value()
    CAN_FRAME.check(value)
    assert value.dlc == frame.dlc and len(value.data) == 8 and value.data[frame.dlc:] == [0] * (8 - frame.dlc)
    assert Frame.from_value(value) == frame
    assert Frame.from_value(CAN_FRAME.to_plain(value)) == frame        # as traces and payloads hold it
    assert Frame.from_value(channels.decode(CAN_FRAME, channels.encode(CAN_FRAME, value))) == frame
    message = frame.to_can_message()
    assert (message.arbitration_id, message.is_remote_frame, message.dlc) == (frame.id, frame.rtr, frame.dlc)
    assert Frame.from_can_message(message) == frame


def test_can_frame_is_a_registered_channel_type():
    assert channels.lookup("canFrame") is CAN_FRAME
    assert channels.REGISTRY["canFrame"] is CAN_FRAME


@pytest.mark.parametrize("value, words", [
    ({"id": 1, "extended": False, "rtr": False, "dlc": 9, "data": [0] * 8}, ["dlc must be 0..8"]),
    ({"id": 1, "extended": False, "rtr": False, "dlc": 2, "data": [0] * 3}, ["8 bytes"]),
    ({"id": 0x800, "extended": False, "rtr": False, "dlc": 0, "data": [0] * 8}, ["11-bit"]),
    ({"id": 1, "rtr": False}, ["missing", "dlc"]),
    ("garbage", ["not a canFrame"]),
])
def test_a_bad_channel_value_is_a_clear_frame_error(value, words):
    with pytest.raises(FrameError) as info:
        Frame.from_value(value)
    for word in words:
        assert word in str(info.value)


def test_error_frames_are_not_frames():
    with pytest.raises(FrameError, match="error frame"):
        Frame.from_can_message(can.Message(arbitration_id=1, is_error_frame=True))


def test_a_bus_is_python_can_s_interface_in_frames_or_messages_and_delivers_to_others_only():
    with open_bus("virtual", "t1", bitrate=None) as a, open_bus("virtual", "t1") as b:
        a.send(odrive.encode(2, "Estop"))                                     # a Frame
        a.send(can.Message(arbitration_id=0x123, data=b"\x01", is_extended_id=False))  # a can.Message
        a.send_frame(odrive.request(2, "Get_Error"))
        assert b.recv_frame(timeout=1.0)[1] == odrive.encode(2, "Estop")
        message = b.recv(timeout=1.0)
        assert isinstance(message, can.Message) and (message.arbitration_id, bytes(message.data)) == (0x123, b"\x01")
        t, frame = b.recv_frame(timeout=1.0)
        assert frame == odrive.request(2, "Get_Error") and t > 0
        assert a.recv(timeout=0.01) is None and b.recv_frame(timeout=0.01) is None
        with pytest.raises(FrameError, match="needs a can.Message or a Frame"):
            a.send(b"\x01")
        with pytest.raises(FrameError, match="needs a Frame"):
            a.send_frame(can.Message(arbitration_id=1))


def test_opening_what_cannot_work_here_says_what_to_do(monkeypatch):
    with pytest.raises(BusUnavailable, match="unknown CAN interface 'serial'"):
        open_bus("serial")
    monkeypatch.delenv("IOTAD_CAN_INTERFACE", raising=False)
    with pytest.raises(BusUnavailable, match="python -m iotad.can.tiers run"):
        open_env_bus()
    try:
        open_bus("socketcan", "vcan0").shutdown()
    except BusUnavailable as exc:  # these machines: no AF_CAN, or no vcan0 outside a namespace
        assert "python -m iotad.can.tiers run" in str(exc) or "ip link add dev vcan0 type vcan" in str(exc)
    if real_interfaces():
        with pytest.raises(BusUnavailable, match="real network interfaces .*private network namespace"):
            open_bus("udp_multicast")


def test_dump_lines_name_the_odrive_message_and_its_signals():
    frame = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0.2, Torque_FF=0.0)
    assert format_frame(1.25, frame, "rx").split() == [
        "1.250000", "rx", "06C", "[8]", "00", "00", "C0", "3F", "C8", "00", "00", "00",
        "Set_Input_Pos", "node=3", "Input_Pos=1.5", "Vel_FF=0.2", "Torque_FF=0"]
    heartbeat = odrive.encode(1, "Heartbeat", Axis_Error=0x1000000, Axis_State=8)
    assert format_frame(0, heartbeat, "tx").endswith(
        "Heartbeat node=1 Axis_Error=WATCHDOG_TIMER_EXPIRED Axis_State=CLOSED_LOOP_CONTROL "
        "Procedure_Result=SUCCESS Trajectory_Done_Flag=0")
    assert format_frame(0, odrive.request(3, "Get_Encoder_Estimates"), "tx").split()[3:] == [
        "[0]", "R", "Get_Encoder_Estimates", "node=3", "request"]


def test_dump_lines_say_unknown_and_malformed():
    assert format_frame(0, Frame(0x7FE, b"\xde\xad"), "rx").split()[-3:] == ["DE", "AD", "unknown"]
    assert format_frame(0, Frame(0x1234567, b"", extended=True), "rx").split()[2:] == ["01234567", "[0]", "unknown"]
    line = format_frame(0, Frame(0x069, b"\xde\xad"), "rx")
    assert "malformed: Get_Encoder_Estimates frame 0x069 (node 3) has DLC 2, the protocol gives 8" in line
    assert "not a CAN frame" in format_frame(0, {"id": 1}, "rx")


def test_dump_lines_of_trace_events():
    event = {"t": 0.5, "iota": "net/bus", "action": "rx", "index": 1, "kind": "output",
             "value": CAN_FRAME.to_plain(odrive.encode(2, "Estop").to_value())}
    assert format_event(event).split() == ["net/bus", "0.500000", "rx[1]", "042", "[0]", "Estop", "node=2"]
    assert format_event({"t": 0, "iota": "x", "action": "ack", "value": "COMMIT"}) is None


def test_frame_fields_for_recordings_name_the_message_where_known():
    fields = frame_fields(2.0, odrive.encode(1, "Set_Axis_State", Axis_Requested_State=8), "tx")
    assert fields == {"t": 2.0, "id": 0x027, "extended": False, "rtr": False, "dlc": 8,
                      "data": [8, 0, 0, 0, 0, 0, 0, 0], "direction": "tx", "name": "Set_Axis_State"}
    assert frame_fields(0, Frame(0x069, b"\x01"), "rx")["name"] is None      # malformed
    assert frame_fields(0, Frame(0x7FE, b""), "rx")["name"] is None           # unknown
