"""The recorded bus log (`iota/<system>/<bus>/frames`) of a virtual-time run names CANopen frames as
CANopen: on examples/arm_canopen.toml every SYNC, NMT command, RPDO, TPDO, SDO and heartbeat is
logged by its service, never as an ODrive message, as `canopen.decode` (and `iotad candump`)
reads the same bytes, and the recording still checks; on a mixed bus (ODrives 1..3, CiA 402 drives
4..6) each frame is named by its family."""
from collections import Counter

import pytest

pytest.importorskip("pybullet")

from arm_hil import ROOT, mixed_canopen_system  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can import odrive  # noqa: E402
from iotad.can.canopen_frame_log import CANOPEN_MESSAGES  # noqa: E402
from iotad.can.frame import Frame  # noqa: E402
from iotad.cli import main  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402

UNTIL = "2"  # s: the drives' start-up (NMT, SDO), then setpoints at every SYNC from t = 0.5


def bus_log(system, path):
    assert main(["run", str(system), "--virtual", "--until", UNTIL, "-o", str(path)]) == 0
    return [e["value"] for e in read_recording(path).trace()
            if e.get("node") == "arm_bus" and e.get("action") == "frames" and e.get("kind") == "output"]


def named(log):
    return Counter((r["id"], r["direction"], r["message"]) for r in log)


def test_a_canopen_bus_logs_sync_pdos_nmt_and_heartbeats_as_canopen(tmp_path, capsys):
    path = tmp_path / "arm.mcap"
    log = bus_log(ROOT / "examples" / "arm_canopen.toml", path)
    assert log and not [r for r in log if r["message"] in odrive.MESSAGES or r["message"] not in CANOPEN_MESSAGES]
    for record in log:  # what candump decodes from the bytes
        assert record["message"] == co.decode(Frame.from_value(record)).kind
    counts = named(log)
    drives = range(1, 7)
    assert counts[(0x080, "TO_AXIS", "SYNC")] > 50                     # every 20 ms once the drives run
    assert counts[(0x000, "TO_AXIS", "NMT")] >= 12                     # pre-operational, start: each drive
    for node in drives:
        assert counts[(0x200 + node, "TO_AXIS", "RPDO1")] > 20         # setpoints
        assert counts[(0x180 + node, "FROM_AXIS", "TPDO1")] > 20       # statusword, position
        assert counts[(0x700 + node, "FROM_AXIS", "HEARTBEAT")] > 0    # the drive's
        assert counts[(0x600 + node, "TO_AXIS", "SDO_REQUEST")] == counts[(0x580 + node, "FROM_AXIS", "SDO_RESPONSE")] > 0
    assert counts[(0x77F, "TO_AXIS", "HEARTBEAT")] > 0                 # the master's (node 127)
    capsys.readouterr()
    assert main(["check", str(path)]) == 0  # the log's bus model rebuilt from the recording conforms
    assert "every node conforms to its spec" in capsys.readouterr().out


def test_a_mixed_bus_logs_each_frame_by_its_family(tmp_path):
    log = bus_log(mixed_canopen_system(tmp_path), tmp_path / "mixed.mcap")
    canopen = [r for r in log if r["message"] in CANOPEN_MESSAGES]
    odrives = [r for r in log if r["message"] in odrive.MESSAGES]
    assert len(canopen) + len(odrives) == len(log)  # nothing UNKNOWN or MALFORMED
    # the ODrives' frames carry their node ids 1..3 (id >> 5), the CANopen ones nodes 4..6 or none
    assert {r["id"] >> 5 for r in odrives} == {1, 2, 3}
    assert {r["message"] for r in odrives} >= {"Heartbeat", "Set_Input_Pos", "Get_Encoder_Estimates"}
    assert {co.decode(Frame.from_value(r)).node_id for r in canopen} <= {0, 4, 5, 6, 127}
    counts = Counter(r["message"] for r in canopen)
    assert counts["SYNC"] > 50 and counts["RPDO1"] > 60 and counts["TPDO1"] > 60 and counts["NMT"] >= 6
    assert counts["HEARTBEAT"] > 0
