"""`BusLogger`, the log of a real-time bus: each frame heard on `can_rx` goes out on `frames`, in
arrival order, as the `canBusFrame` record the modelled bus writes, but with no station (a real
bus does not say who sent a frame), its bit time at the bus's bitrate, CAN Simple direction and
message name."""
from iotad.can import odrive
from iotad.can.frame import Frame
from iotad.can.frame_log import CAN_BUS_FRAME, BusLogger
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine


def logged(frames_at, **params):
    engine = Engine(BusLogger("can0", **params), VirtualClock())
    for t, frame in frames_at:
        engine.post(None, "can_rx", frame.to_value(), t=t)
    engine.run(1.0)
    return [(e["t"], e["value"]) for e in engine.trace if e["action"] == "frames" and e["kind"] == "output"]


def test_each_frame_heard_is_logged_at_once_in_order_without_a_station():
    heartbeat = odrive.encode(3, "Heartbeat", Axis_State=8)
    command = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5)
    ask = odrive.request(3, "Get_Encoder_Estimates")
    other = Frame(0x1ABCDEF, b"\x01\x02", extended=True)
    out = logged([(0.1, command), (0.1, ask), (0.2, heartbeat), (0.3, other)])
    assert [t for t, _ in out] == [0.1, 0.1, 0.2, 0.3]
    records = [value for _, value in out]
    assert [r["station"] for r in records] == [None] * 4
    assert [(r["direction"], r["message"]) for r in records] == [
        ("TO_AXIS", "Set_Input_Pos"), ("TO_AXIS", "Get_Encoder_Estimates"), ("FROM_AXIS", "Heartbeat"),
        ("NOT_ODRIVE", "UNKNOWN")]
    assert [Frame.from_value(r) for r in records] == [command, ask, heartbeat, other]
    # the record's plain form is the modelled bus's: the same fields, station null
    assert set(records[0]) == set(CAN_BUS_FRAME.field_names)


def test_the_duration_is_the_frames_bit_time_at_the_bus_bitrate():
    frame = Frame(0x06C, bytes(8))
    (_, fast), = logged([(0.0, frame)])
    (_, slow), = logged([(0.0, frame)], bitrate=250_000)
    assert 111e-6 <= fast["duration"] <= 135e-6  # 8 data bytes at 1 Mbit/s, stuff bits included
    assert abs(slow["duration"] - 4 * fast["duration"]) < 1e-12
