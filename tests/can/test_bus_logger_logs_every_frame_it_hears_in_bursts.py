"""`BusLogger`, the log of a real-time bus, writes recording format 2: the frames heard on `can_rx`
within `batch` of the first go out as one `burst`, in arrival order, each with the fields the
modelled bus's bursts have, but with no station (a real bus does not say who sent a frame), its
arrival as its wire end, its bit time at the bus's bitrate, CAN Simple direction and message name;
read back, each frame is the `frames` log record of format 1 at its arrival."""
import pytest

from iotad.can import odrive
from iotad.can.burst_types import BURST_FIELDS
from iotad.can.frame import Frame
from iotad.can.frame_log import CAN_BUS_FRAME, BusLogger
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.recording.bursts import frame_events


def bursts(frames_at, **params):
    engine = Engine(BusLogger("can0", **params), VirtualClock())
    for t, frame in frames_at:
        engine.post(None, "can_rx", frame.to_value(), t=t)
    engine.run(1.0)
    return [(e["t"], e["value"]) for e in engine.trace if e["action"] == "burst" and e["kind"] == "output"]


def logged(frames_at, **params):
    """(t, record) of each frame as a reader expands the bursts: format 1's `frames` log."""
    return [(e["t"], e["value"]) for t, value in bursts(frames_at, **params)
            for e in frame_events({"t": t, "iota": "can0", "action": "burst", "kind": "output", "value": value}, 0)]


HEARTBEAT = odrive.encode(3, "Heartbeat", Axis_State=8)
COMMAND = odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5)
ASK = odrive.request(3, "Get_Encoder_Estimates")
OTHER = Frame(0x1ABCDEF, b"\x01\x02", extended=True)


def test_the_frames_heard_within_a_batch_go_out_as_one_burst():
    out = bursts([(0.1, COMMAND), (0.1, ASK), (0.102, HEARTBEAT), (0.3, OTHER)], batch=0.005)
    assert [(t, len(value)) for t, value in out] == [(pytest.approx(0.105), 3), (pytest.approx(0.305), 1)]
    frames = [f for _, value in out for f in value]
    assert [f["order"] for f in frames] == [0, 1, 2, 3]
    assert [f["end"] for f in frames] == [0.1, 0.1, 0.102, 0.3]  # each frame's arrival
    assert all(set(f) == set(BURST_FIELDS) and f["station"] is None for f in frames)
    assert all(f["start"] == pytest.approx(f["end"] - f["duration"]) for f in frames)


def test_read_back_each_frame_is_logged_at_its_arrival_in_order_without_a_station():
    out = logged([(0.1, COMMAND), (0.1, ASK), (0.2, HEARTBEAT), (0.3, OTHER)])
    assert [t for t, _ in out] == [0.1, 0.1, 0.2, 0.3]
    records = [value for _, value in out]
    assert [r["station"] for r in records] == [None] * 4
    assert [(r["direction"], r["message"]) for r in records] == [
        ("TO_AXIS", "Set_Input_Pos"), ("TO_AXIS", "Get_Encoder_Estimates"), ("FROM_AXIS", "Heartbeat"),
        ("NOT_ODRIVE", "UNKNOWN")]
    assert [Frame.from_value(r) for r in records] == [COMMAND, ASK, HEARTBEAT, OTHER]
    # the record's plain form is the modelled bus's log: the same fields, station null; a logger
    # has no rx outputs to stand for
    assert set(records[0]) == set(CAN_BUS_FRAME.field_names)


def test_the_duration_is_the_frames_bit_time_at_the_bus_bitrate():
    frame = Frame(0x06C, bytes(8))
    (_, fast), = logged([(0.0, frame)])
    (_, slow), = logged([(0.0, frame)], bitrate=250_000)
    assert 111e-6 <= fast["duration"] <= 135e-6  # 8 data bytes at 1 Mbit/s, stuff bits included
    assert abs(slow["duration"] - 4 * fast["duration"]) < 1e-12


def test_a_batch_longer_than_the_lag_is_refused():
    with pytest.raises(ValueError, match="batch"):
        BusLogger("can0", batch=0.5, lag=0.1)


def test_frames_its_port_received_together_are_logged_as_if_heard_one_by_one():
    together = Engine(BusLogger("can0"), VirtualClock())
    together.post(None, "can_rx_burst", [COMMAND.to_value(), ASK.to_value(), HEARTBEAT.to_value()], t=0.1)
    together.run(1.0)
    out = [f for e in together.trace if e["action"] == "burst" for f in e["value"]]
    assert out == [f for _, value in bursts([(0.1, COMMAND), (0.1, ASK), (0.1, HEARTBEAT)]) for f in value]
