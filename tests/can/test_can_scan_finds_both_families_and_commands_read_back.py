"""`iotad can` on a bus with two simulated ODrive axes and two simulated CiA 402 drives: scan lists
exactly those four with their protocol, firmware and hardware versions, state, errors and bus
voltage; clear-errors resets a faulted drive and arm enables it, each read back; a command to an
axis that a running system's motor node holds (its liveliness token and @spec on a zenoh hub) is
refused unless --force; a node that does not answer is a clear failure, not a hang."""
import itertools

import pytest

from iotad.cli import main
from iotad.node_host import wire
from iotad.node_host.transport import free_port, open_session
from simulated_bus_drives import BusDrives

_channels = itertools.count()


@pytest.fixture
def drives():
    with BusDrives(f"iotad-can-test-{next(_channels)}") as bus:
        yield bus


def can(drives, *args):
    return main(["can", *args, "--interface", "virtual", "--channel", drives.channel, "--hub-timeout", "0"])


def test_scan_finds_exactly_the_drives_of_both_families_with_their_states(drives, capsys):
    assert can(drives, "scan") == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:5] == ["protocol", "node", "firmware", "hardware", "state"]
    rows = [line.split() for line in lines[1:]]
    assert [(r[0], int(r[1])) for r in rows] == [("odrive", 1), ("odrive", 2), ("cia402", 5), ("cia402", 6)]
    odrive_row = lines[1]
    assert "0.6.10" in odrive_row and "4.4.58" in odrive_row and "IDLE" in odrive_row and "24.0" in odrive_row
    cia_row = lines[3]
    assert "SWITCH ON DISABLED" in cia_row and "48.0" in cia_row
    # the drive's strings, 0x100A (software) and 0x1009 (hardware) over 4 bytes: segmented SDO
    assert "iotad-drive 0.2.0 (rev 0x00010000)" in cia_row and "sim-board 1.0" in cia_row
    assert cia_row.endswith("iotad simulated CiA 402 drive")  # 0x1008, the device name


def test_clear_errors_and_arm_read_back_their_result(drives, capsys):
    with drives.lock:
        drives.drives[5].fault(0x2310)  # an over-current: FAULT
    assert can(drives, "status", "--node", "5") == 0
    assert "FAULT" in capsys.readouterr().out
    assert can(drives, "arm", "--node", "5") == 1
    assert "in FAULT (0x2310 continuous over-current); run clear-errors first" in capsys.readouterr().err
    assert can(drives, "clear-errors", "--node", "5") == 0
    assert "clear-errors done: SWITCH ON DISABLED, errors: none" in capsys.readouterr().out
    assert can(drives, "arm", "--node", "5") == 0
    assert "arm done: OPERATION ENABLED" in capsys.readouterr().out
    with drives.lock:
        assert drives.drives[5].state == "OPERATION ENABLED"
        drives.axes[2].fault(0x1000000)  # a watchdog error on the ODrive
    assert can(drives, "clear-errors", "--node", "2") == 0
    assert can(drives, "arm", "--node", "2") == 0
    assert "arm done: CLOSED_LOOP_CONTROL" in capsys.readouterr().out
    assert can(drives, "idle", "--node", "2") == 0 and can(drives, "estop", "--node", "5") == 0
    out = capsys.readouterr().out
    assert "idle done: IDLE" in out
    # quick stop (transition 11), then, standing still, the end of its ramp (12, option code 2)
    assert "estop done: QUICK STOP ACTIVE" in out or "estop done: SWITCH ON DISABLED" in out
    with drives.lock:
        assert drives.drives[5].transitions[-2:] in ([4, 11], [11, 12])


def test_set_limits_takes_si_units_and_reads_them_back(drives, capsys):
    assert can(drives, "set-limits", "--node", "6", "--velocity", "6.283185307", "--torque", "2.5") == 0
    out = capsys.readouterr().out
    assert "velocity_limit_rad_s=6.28" in out and "torque_limit_nm=2.5" in out
    with drives.lock:
        assert drives.drives[6].values[(0x607F, 0)] == 65536  # one turn/s on the wire: increments


def test_a_silent_node_is_a_clear_failure(drives, capsys):
    assert can(drives, "arm", "--node", "9") == 1
    assert "node 9: no ODrive (Get_Version) or CiA 402 drive (SDO 0x1018) answered" in capsys.readouterr().err


def test_a_held_axis_is_refused_unless_forced(drives, capsys):
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    session = open_session([endpoint], credentials=False)
    try:
        token = session.liveliness().declare_token("iota/held/motor/@alive")
        spec = {"params": {"joints": [{"name": "a", "node_id": 5, "protocol": "cia402"}]}}
        queryable = session.declare_queryable("iota/held/motor/@spec", lambda query: query.reply(query.key_expr, wire.encode(spec)))
        args = ["can", "arm", "--node", "5", "--interface", "virtual", "--channel", drives.channel,
                "--connect", endpoint, "--hub-timeout", "2"]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert "node 5 (cia402) is held by the running motor node held/motor" in err
        # what clears a held FAULT is the node's own reset (docs/can_motor.md), and the refusal says how
        assert "re-armed by its reset: iotad pub iota/held/motor/estop false" in err
        with drives.lock:
            drives.drives[5].fault(0x2310)
        clear = ["can", "clear-errors", *args[2:]]
        assert main(clear) == 2 and "is held by the running motor node" in capsys.readouterr().err
        with drives.lock:
            assert drives.drives[5].state == "FAULT"  # refused: the fault stays
        assert main(clear + ["--force"]) == 0
        with drives.lock:
            assert drives.drives[5].state == "SWITCH ON DISABLED"  # nothing was sent to it
        assert main(args + ["--force"]) == 0
        # the ODrive at 1 is nobody's: commanded without --force
        assert main(["can", "arm", "--node", "1", "--interface", "virtual", "--channel", drives.channel,
                     "--connect", endpoint, "--hub-timeout", "2"]) == 0
        queryable.undeclare()
        token.undeclare()
    finally:
        session.close()
