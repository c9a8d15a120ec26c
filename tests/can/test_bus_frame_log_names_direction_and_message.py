"""The modelled bus's frame log (`CanBus.frames`, one recorded topic per bus): one record per frame
as it ends, with its sender, bit time and bytes, and its CAN Simple direction and message name;
frames CAN Simple does not know are logged too, as UNKNOWN or MALFORMED; `log_frames = false`
switches the log off."""
import pytest

from iotad import Engine
from iotad.can import odrive
from iotad.can.bit_timing import frame_bits
from iotad.can.frame import Frame
from iotad.can.frame_log import CAN_BUS_FRAME, bus_frame, classify
from iotad.can.virtual_bus import CanBus


def test_classify_by_the_protocol():
    assert classify(odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0, Torque_FF=0)) == ("TO_AXIS", "Set_Input_Pos")
    assert classify(odrive.request(3, "Get_Error")) == ("TO_AXIS", "Get_Error")       # a remote request
    assert classify(odrive.encode(3, "Get_Error", Active_Errors=1, Disarm_Reason=0)) == ("FROM_AXIS", "Get_Error")
    assert classify(odrive.encode(3, "Address", Node_ID=3, Serial_Number=7)) == ("EITHER", "Address")
    assert classify(Frame(0x069, b"\x01")) == ("FROM_AXIS", "MALFORMED")  # Get_Encoder_Estimates, 1 byte
    assert classify(Frame(0x07E, b"")) == ("NOT_ODRIVE", "UNKNOWN")       # cmd 0x1E: none
    assert classify(Frame(0x123456, b"\x01", extended=True)) == ("NOT_ODRIVE", "UNKNOWN")


def test_a_record_is_a_checked_channel_value():
    record = bus_frame(Frame.remote(0x069, 8).to_value(), 2, 5e-5)
    CAN_BUS_FRAME.check(record)
    assert (record.station, record.rtr, record.dlc, record.data, record.message) == (2, True, 8, [0] * 8,
                                                                                     "Get_Encoder_Estimates")


def bus_run(**params):
    bus = CanBus("bus", stations=2, load_period=0, **params)
    engine = Engine(bus)
    sent = [(0, Frame(0x7FE, b"\xff" * 3)), (1, odrive.encode(1, "Heartbeat", Axis_Error=0, Axis_State=8,
                                                             Procedure_Result=0, Trajectory_Done_Flag=1)),
            (0, odrive.encode(1, "Clear_Errors", Identify=0))]
    for station, frame in sent:
        engine.post(None, "tx", frame.to_value(), index=station, t=0.0)
    return engine.run(until=0.01), sent


def test_every_frame_is_logged_once_as_it_ends():
    trace, sent = bus_run()
    logged = [(e["t"], e["value"]) for e in trace if e["action"] == "frames"]
    delivered = [e["t"] for e in trace if e["action"] == "rx"]
    assert [t for t, _ in logged] == delivered  # the end of each frame
    # arbitration: Heartbeat (0x021) before Clear_Errors (0x038); station 0's FIFO holds 0x7FE first
    by_id = {frame.id: (station, frame) for station, frame in sent}
    assert [v["id"] for _, v in logged] == [0x021, 0x7FE, 0x038]
    for _, value in logged:
        station, frame = by_id[value["id"]]
        assert value["station"] == station and value["data"][:value["dlc"]] == list(frame.data)
        assert value["duration"] == pytest.approx(frame_bits(frame.id, False, False, frame.data, "exact") * 1e-6, abs=1e-15)
    assert [(v["direction"], v["message"]) for _, v in logged] == [
        ("FROM_AXIS", "Heartbeat"), ("NOT_ODRIVE", "UNKNOWN"), ("TO_AXIS", "Clear_Errors")]


def test_the_log_can_be_switched_off():
    trace, _ = bus_run(log_frames=False)
    assert not [e for e in trace if e["action"] == "frames"] and len([e for e in trace if e["action"] == "rx"]) == 3
