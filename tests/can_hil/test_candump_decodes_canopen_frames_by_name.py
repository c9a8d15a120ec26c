"""`iotad candump` decodes the CANopen frames of a recording of CiA 402 drives (examples/arm_canopen.toml,
virtual time) as it decodes ODrive frames: NMT, SYNC, SDO writes with the object's name, PDOs by the
mapping those writes set, heartbeats; an EMCY with its error code by name; a CANopen frame of the
wrong length as malformed, never a crash."""
import pytest

pytest.importorskip("pybullet")

from arm_hil import ROOT  # noqa: E402
from iotad.can import canopen as co  # noqa: E402
from iotad.can.dump import format_frame  # noqa: E402
from iotad.can.frame import Frame  # noqa: E402
from iotad.cli import main  # noqa: E402


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("co") / "arm.mcap"
    assert main(["run", str(ROOT / "examples" / "arm_canopen.toml"), "--virtual", "--until", "0.8", "-o", str(path)]) == 0
    return path


def test_candump_names_each_canopen_service(recording, capsys):
    assert main(["candump", str(recording)]) == 0
    out = capsys.readouterr().out
    assert "NMT ENTER_PRE_OPERATIONAL node=1" in out and "NMT START node=6" in out
    assert "SDO download node=2 0x6060.00 Modes of operation = 8" in out
    assert "SDO response download node=2 0x6060.00 Modes of operation" in out
    assert "SDO download node=3 0x1A00.01 Mapped object 1 = 0x60410010" in out
    assert "  SYNC" in out and "Heartbeat node=4 OPERATIONAL" in out and "Heartbeat node=127 OPERATIONAL" in out
    assert "TPDO1 node=5 Statusword=0x1237(OPERATION ENABLED) Position_actual_value=" in out
    assert "RPDO1 node=5 Controlword=0x000F(ENABLE OPERATION) Target_position=" in out
    assert "unknown" not in out and "malformed" not in out


def test_emcy_by_name_and_a_short_frame_as_malformed():
    tracker = co.PdoTracker([3])
    line = format_frame(1.0, co.emcy(3, 0x8130, 0x11), "rx", tracker)
    assert line.endswith("EMCY node=3 0x8130 life guard error or heartbeat error register=0x11")
    assert "malformed: EMCY 0x083 with 2 bytes" in format_frame(1.0, Frame(0x083, b"\x30\x81"), "rx", tracker)
    assert "TPDO1 node=3 malformed: PDO of 3 bytes; its mapping is 8 bytes" in format_frame(
        1.0, Frame(0x183, b"\0\0\0"), "rx", tracker)
    # without CiA 402 node ids the same id is an ODrive frame, as before
    assert "CANopen" not in format_frame(1.0, Frame(0x083, b"\x30\x81"), "rx") and "EMCY" not in format_frame(
        1.0, Frame(0x083, b"\x30\x81"), "rx")
