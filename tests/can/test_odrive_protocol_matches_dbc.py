"""iotad.can.odrive encodes and decodes every ODrive CAN Simple message byte for byte as the
firmware 0.6.10 DBC does through cantools, for every axis Axis0_..Axis7_; bad frames raise FrameError."""
import math
import struct
from pathlib import Path

import pytest

cantools = pytest.importorskip("cantools")
from hypothesis import given, settings, strategies as st  # noqa: E402

from iotad.can import odrive  # noqa: E402
from iotad.can.frame import Frame, FrameError  # noqa: E402

DBC = Path(__file__).parent / "data" / "odrive-cansimple-0.6.10.dbc"
NODES = range(8)


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(DBC)


def dbc_message(db, node, name):
    return db.get_message_by_name(f"Axis{node}_{name}")


def value_sets(spec):
    """Several signal value sets for a message: zeros, typical values, both ends of each range."""
    if not spec.signals:
        return [{}]
    sets = [{s.name: 0 for s in spec.signals}]
    typical, low, high = {}, {}, {}
    for index, s in enumerate(spec.signals):
        if s.kind == "f":
            typical[s.name] = [1.5, -0.25, 3.1415927, 1234.5678, -9.87e-3, 2.0 ** -20][index % 6]
            low[s.name], high[s.name] = -3.4e38, 3.4e38
        elif s.kind == "i":
            typical[s.name] = [0.2, -1.234, 0.001][index % 3]
            low[s.name] = -(1 << (s.length - 1)) * s.scale
            high[s.name] = ((1 << (s.length - 1)) - 1) * s.scale
        else:
            top = (1 << s.length) - 1
            typical[s.name] = min(top, [8, 3, 1, 0x1000800, 0x1234][index % 5])
            low[s.name], high[s.name] = 0, top
    return sets + [typical, low, high]


def same_value(ours, theirs):
    if isinstance(theirs, float) or isinstance(ours, float):
        return math.isclose(ours, theirs, rel_tol=0, abs_tol=1e-12) or ours == theirs
    return ours == theirs


def test_the_message_table_is_the_dbc(db):
    for node in NODES:
        names = {m.name.split("_", 1)[1] for m in db.messages if m.name.startswith(f"Axis{node}_")}
        assert names == set(odrive.COMMANDS), f"axis {node}"
        for name, spec in odrive.MESSAGES.items():
            message = dbc_message(db, node, name)
            assert message.frame_id == node << 5 | spec.cmd_id == odrive.frame_id(node, name)
            assert message.length == spec.dlc, name
            assert {s.name for s in message.signals} == set(spec.signal_names), name
            senders = {"host": ["Master"], "axis": [f"ODrive_Axis{node}"], "both": ["Master", f"ODrive_Axis{node}"]}
            assert message.senders == senders[spec.sender], name
            cycle = message.cycle_time / 1000 if message.cycle_time else None
            assert cycle == spec.cycle_time, name


@pytest.mark.parametrize("name", sorted(odrive.MESSAGES))
def test_encode_is_byte_for_byte_the_dbc(db, name):
    spec = odrive.MESSAGES[name]
    for node in NODES:
        message = dbc_message(db, node, name)
        for values in value_sets(spec):
            frame = odrive.encode(node, name, **values)
            expected = message.encode(values, scaling=True, padding=False, strict=True)
            assert frame.id == message.frame_id and not frame.extended and not frame.rtr
            assert frame.data == bytes(expected), f"{name} node {node} {values}"
            assert frame.dlc == message.length


@pytest.mark.parametrize("name", sorted(odrive.MESSAGES))
def test_decode_is_the_dbc_decoding(db, name):
    spec = odrive.MESSAGES[name]
    for node in NODES:
        message = dbc_message(db, node, name)
        for values in value_sets(spec):
            data = message.encode(values, scaling=True, padding=False, strict=True)
            decoded = odrive.decode(Frame(message.frame_id, bytes(data)))
            theirs = message.decode(data, decode_choices=False, scaling=True)
            assert (decoded.node_id, decoded.name, decoded.rtr) == (node, name, False)
            assert decoded.signals.keys() == theirs.keys()
            for signal, value in theirs.items():
                assert same_value(decoded.signals[signal], value), f"{name}.{signal} node {node}"


@settings(max_examples=200, deadline=None)
@given(name=st.sampled_from(sorted(n for n, s in odrive.MESSAGES.items() if s.dlc)),
       node=st.integers(0, 7), data=st.binary(min_size=8, max_size=8))
def test_any_bytes_decode_as_cantools_and_encode_back(db, name, node, data):
    spec = odrive.MESSAGES[name]
    data = data[:spec.dlc]
    message = dbc_message(db, node, name)
    ours = odrive.decode(Frame(message.frame_id, data))
    theirs = message.decode(data, decode_choices=False, scaling=True)
    for signal, value in theirs.items():
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(ours.signals[signal])
        else:
            assert same_value(ours.signals[signal], value)
    if any(isinstance(v, float) and math.isnan(v) for v in ours.signals.values()):
        return  # NaN payloads differ in their mantissa bits; not a value anyone sends
    # the bits no signal covers are padding (zero); the rest encodes back to the same bytes
    covered = sum(((1 << s.length) - 1) << s.start for s in spec.signals)
    expected = (int.from_bytes(data, "little") & covered).to_bytes(8, "little")[:spec.dlc]
    assert odrive.encode(node, name, **ours.signals).data == expected


def test_the_example_of_the_interface():
    frame = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0.2, Torque_FF=0.0)
    assert frame.id == 3 << 5 | 0x0C
    assert frame.data == struct.pack("<fhh", 1.5, 200, 0)
    assert odrive.encode(1, "Set_Axis_State", Axis_Requested_State=odrive.AXIS_STATE["CLOSED_LOOP_CONTROL"]).data \
        == bytes([8, 0, 0, 0, 0, 0, 0, 0])  # DLC 8, zero-padded, as the DBC gives
    assert odrive.encode(2, "Estop").data == b""
    assert odrive.encode(2, "Clear_Errors").data == b"\x00"


def test_requests_are_remote_frames_and_decode_as_requests():
    frame = odrive.request(5, "Get_Encoder_Estimates")
    assert (frame.id, frame.rtr, frame.dlc) == (5 << 5 | 0x09, True, 0)
    message = odrive.decode(frame)
    assert (message.node_id, message.name, message.rtr, message.signals) == (5, "Get_Encoder_Estimates", True, {})
    assert odrive.decode(Frame.remote(5 << 5 | 0x03, dlc=8)).name == "Get_Error"  # any DLC on a request


def test_watchdog_error_is_the_0_6_firmware_flag(db):
    assert odrive.AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"] == 0x01000000
    choices = dbc_message(db, 0, "Heartbeat").get_signal_by_name("Axis_Error").choices
    assert {str(label): int(value) for value, label in choices.items()} == odrive.AXIS_ERROR
    for table, signal, message in ((odrive.AXIS_STATE, "Axis_State", "Heartbeat"),
                                   (odrive.INPUT_MODE, "Input_Mode", "Set_Controller_Mode"),
                                   (odrive.PROCEDURE_RESULT, "Procedure_Result", "Heartbeat")):
        choices = dbc_message(db, 0, message).get_signal_by_name(signal).choices
        assert {str(label): int(value) for value, label in choices.items()} == table
    choices = dbc_message(db, 0, "Set_Controller_Mode").get_signal_by_name("Control_Mode").choices
    assert {str(label).removesuffix("_CONTROL"): int(v) for v, label in choices.items()} == odrive.CONTROL_MODE


@pytest.mark.parametrize("frame, error, words", [
    (Frame(3 << 5 | 0x09, bytes(4)), odrive.MalformedFrame, ["Get_Encoder_Estimates", "DLC 4", "gives 8"]),
    (Frame(3 << 5 | 0x07, bytes(4)), odrive.MalformedFrame, ["Set_Axis_State", "DLC 4"]),
    (Frame(1 << 5 | 0x02, b"\x01"), odrive.MalformedFrame, ["Estop", "DLC 1", "gives 0"]),
    (Frame(3 << 5 | 0x08, bytes(8)), odrive.UnknownFrame, ["0x068", "cmd 0x08"]),
    (Frame(0x7FE, b"\xde\xad\xbe\xef"), odrive.UnknownFrame, ["0x7FE", "node 63", "0x1E"]),
    (Frame(0x7FF, b"\xde\xad\xbe\xef"), odrive.MalformedFrame, ["Enter_DFU_Mode", "DLC 4"]),
    (Frame(3 << 5 | 0x09, bytes(8), extended=True), odrive.MalformedFrame, ["extended", "11-bit"]),
    ("garbage", odrive.MalformedFrame, ["expected a Frame", "str"]),
])
def test_malformed_frames_raise_a_clear_frame_error(frame, error, words):
    with pytest.raises(error) as info:
        odrive.decode(frame)
    assert isinstance(info.value, FrameError) and isinstance(info.value, ValueError)
    for word in words:
        assert word in str(info.value)


@pytest.mark.parametrize("call, words", [
    (lambda: odrive.encode(1, "Set_Input_Pos", Vel_FF=40.0), ["Vel_FF=40.0", "out of range", "32767"]),
    (lambda: odrive.encode(1, "Set_Input_Pos", Input_Position=1.0), ["no signal", "Input_Pos"]),
    (lambda: odrive.encode(1, "Set_Input_Position"), ["no ODrive CAN Simple message", "Set_Input_Pos"]),
    (lambda: odrive.encode(64, "Estop"), ["node id", "0..63"]),
    (lambda: odrive.encode(1, "Set_Axis_State", Axis_Requested_State=-1), ["out of range"]),
    (lambda: odrive.encode(1, "Set_Input_Vel", Input_Vel=1e39), ["float32"]),
    (lambda: odrive.encode(1, "Set_Input_Vel", Input_Vel="fast"), ["needs a number"]),
    (lambda: Frame(0x800, b""), ["11-bit"]),
    (lambda: Frame(1, bytes(9)), ["at most 8"]),
    (lambda: Frame(1, b"\x01", rtr=True), ["RTR"]),
])
def test_bad_encodings_raise_a_clear_frame_error(call, words):
    with pytest.raises(FrameError) as info:
        call()
    for word in words:
        assert word in str(info.value)
