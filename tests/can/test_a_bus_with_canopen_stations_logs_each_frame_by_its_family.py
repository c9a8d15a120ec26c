"""A bus whose stations declare CiA 402 node ids logs each frame by its family: NMT, SYNC, EMCY,
SDO, PDOs and heartbeats as CANopen (for those node ids), the rest as ODrive CAN Simple, in the
modelled bus of virtual time (`CanopenCanBus`) and in the real-time bus logger
(`CanopenBusLogger`), which `iotad run` picks from the stations' params. A bus of ODrives only
keeps `CanBus`/`BusLogger` and the `canBusFrame` record, unchanged."""
import pytest

from iotad import Engine
from iotad.can import canopen as co
from iotad.can import odrive
from iotad.can.canopen_frame_log import (CANOPEN_BUS_FRAME, CANOPEN_MESSAGES, CanopenBusLogger, CanopenCanBus,
                                         canopen_classify)
from iotad.can.burst_bus import BurstCanBus, BurstCanopenCanBus
from iotad.can.frame import Frame
from iotad.can.frame_log import CAN_BUS_FRAME, BusLogger
from iotad.can.virtual_bus import CanBus
from iotad.kernel.clock import VirtualClock
from iotad.launcher.system.declaration import CANOPEN_LOGGER_REF, LOGGER_REF
from iotad.launcher.system.in_process import compose
from iotad.launcher.system.system_file import load_system

ROOT = __import__("pathlib").Path(__file__).resolve().parents[2]
DRIVES = frozenset({4, 5, 6})  # a mixed bus: ODrives 1..3, CiA 402 drives 4..6, the master 127

FAMILIES = [  # (frame, direction, message)
    (co.sync(), "TO_AXIS", "SYNC"),                                   # 0x080: an ODrive's Get_Version by id
    (co.nmt("START", 4), "TO_AXIS", "NMT"),
    (co.nmt("RESET_NODE"), "TO_AXIS", "NMT"),                         # to every node
    (Frame(0x204, bytes(6)), "TO_AXIS", "RPDO1"),
    (Frame(0x185, bytes(6)), "FROM_AXIS", "TPDO1"),
    (Frame(0x285, bytes(8)), "FROM_AXIS", "TPDO2"),
    (co.heartbeat(5, "OPERATIONAL"), "FROM_AXIS", "HEARTBEAT"),       # a drive's
    (co.heartbeat(127, "OPERATIONAL"), "TO_AXIS", "HEARTBEAT"),       # the master's, that the drives watch
    (co.sdo_download(6, 0x6060, 0, bytes([8])), "TO_AXIS", "SDO_REQUEST"),
    (co.sdo_download_response(6, 0x6060, 0), "FROM_AXIS", "SDO_RESPONSE"),
    (co.emcy(4, 0x8611, 0x80), "FROM_AXIS", "EMCY"),
    (Frame(co.SYNC, bytes(3)), "TO_AXIS", "MALFORMED"),               # CANopen's id, not its shape
    (Frame(0x704, b""), "FROM_AXIS", "MALFORMED"),
    (odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0, Torque_FF=0), "TO_AXIS", "Set_Input_Pos"),
    (odrive.encode(1, "Heartbeat", Axis_Error=0, Axis_State=8, Procedure_Result=0, Trajectory_Done_Flag=1),
     "FROM_AXIS", "Heartbeat"),
    (Frame(0x1ABCDEF, b"\x01", extended=True), "NOT_ODRIVE", "UNKNOWN"),
]


@pytest.mark.parametrize("frame, direction, message", FAMILIES, ids=[m for _, _, m in FAMILIES])
def test_each_frame_is_named_by_its_family(frame, direction, message):
    assert canopen_classify(frame, DRIVES) == (direction, message)


def test_a_canopen_node_ids_frames_are_odrive_frames_where_the_bus_has_no_such_drive():
    # 0x185 is TPDO1 of node 5; on a bus whose CiA 402 drives are 1..3 it is no CANopen service
    assert canopen_classify(Frame(0x185, bytes(6)), frozenset({1, 2, 3}))[1] != "TPDO1"
    assert canopen_classify(co.sync(), frozenset({1})) == ("TO_AXIS", "SYNC")


def bus_log(bus, sent):
    """The bus's log of the frames it carried: its `frames` outputs (format 1), or the frames of
    its bursts (format 2), as records of a frame's fields and its direction and message."""
    engine = Engine(bus)
    for t, (station, frame) in enumerate(sent):
        engine.post(None, "tx", frame.to_value(), index=station, t=t * 1e-3)
    trace = engine.run(until=0.1)
    fields = ("station", "id", "extended", "rtr", "dlc", "data", "direction", "message")
    return [{k: f[k] for k in fields} for e in trace if e["kind"] == "output"
            for f in ([e["value"]] if e["action"] == "frames" else e["value"] if e["action"] == "burst" else [])]


@pytest.mark.parametrize("canopen_bus, plain_bus", [(CanopenCanBus, CanBus), (BurstCanopenCanBus, BurstCanBus)],
                         ids=["format1", "format2"])
def test_the_modelled_bus_logs_canopen_and_odrive_frames_by_family_in_bus_order(canopen_bus, plain_bus):
    sent = [(0, frame) for frame, _, _ in FAMILIES]
    log = bus_log(canopen_bus("bus", stations=2, load_period=0, canopen=sorted(DRIVES)), sent)
    assert [(r["direction"], r["message"]) for r in log] == [(d, m) for _, d, m in FAMILIES]
    assert [Frame.from_value({k: r[k] for k in ("id", "extended", "rtr", "dlc", "data")}) for r in log] \
        == [frame for _, frame in sent]
    assert {r["station"] for r in log} == {0}
    # the plain CanBus names the same frames as CAN Simple: SYNC is Get_Version's id there, too short
    plain = bus_log(plain_bus("bus", stations=2, load_period=0), sent[:1])
    assert (plain[0]["id"], plain[0]["message"]) == (0x080, "MALFORMED")


def test_the_real_time_logger_names_frames_by_family_too():
    engine = Engine(CanopenBusLogger("can0", canopen=sorted(DRIVES)), VirtualClock())
    for t, (frame, _, _) in enumerate(FAMILIES):
        engine.post(None, "can_rx", frame.to_value(), t=t * 1e-3)
    engine.run(1.0)
    log = [f for e in engine.trace if e["action"] == "burst" and e["kind"] == "output" for f in e["value"]]
    assert [(r["direction"], r["message"], r["station"]) for r in log] == [(d, m, None) for _, d, m in FAMILIES]


def test_the_canopen_log_is_the_canbusframe_record_with_canopen_messages():
    assert CANOPEN_BUS_FRAME.field_names == CAN_BUS_FRAME.field_names
    messages = set(CANOPEN_BUS_FRAME.fields["message"].members)
    assert set(CANOPEN_MESSAGES) <= messages and set(odrive.MESSAGES) <= messages
    assert not set(CANOPEN_MESSAGES) & set(CAN_BUS_FRAME.fields["message"].members)


@pytest.mark.parametrize("bad", [[0], [128], ["1"], "1,2", [True]])
def test_node_ids_out_of_range_are_refused_in_words(bad):
    with pytest.raises(ValueError, match="CANopen node ids 1..127"):
        CanopenCanBus("bus", canopen=bad)


def test_iotad_run_picks_the_log_by_the_stations_params():
    canopen = load_system(ROOT / "examples" / "arm_canopen.toml")
    logger = canopen.nodes["arm_bus"]
    assert logger.source["ref"] == CANOPEN_LOGGER_REF and logger.params["canopen"] == [1, 2, 3, 4, 5, 6]
    assert logger.channels["frames"].type is CANOPEN_BUS_FRAME  # the node is checked as it will run
    bus = compose(canopen).components["arm_bus"]
    assert type(bus) is BurstCanopenCanBus and bus.canopen == [1, 2, 3, 4, 5, 6]  # format 2
    bus = compose(canopen, 1).components["arm_bus"]
    assert type(bus) is CanopenCanBus and bus.canopen == [1, 2, 3, 4, 5, 6]
    # a bus of ODrives only: the plain logger and model, their params as before
    odrives = load_system(ROOT / "examples" / "arm_can.toml")
    assert odrives.nodes["arm_bus"].source["ref"] == LOGGER_REF and "canopen" not in odrives.nodes["arm_bus"].params
    assert type(compose(odrives).components["arm_bus"]) is BurstCanBus  # format 2
    bus = compose(odrives, 1).components["arm_bus"]
    assert type(bus) is CanBus and BusLogger.frames.type is CAN_BUS_FRAME
