"""`iotad can` tools change only what they say, and read state where the drive keeps it:

- clear-errors on an enabled CiA 402 drive sends nothing and says so, with the statusword read
  back: the drive stays OPERATION ENABLED (the old tool wrote controlword 0x0000, "disable
  voltage", transition 9, and switched its power stage off);
- clear-errors on a faulted drive is a fault reset: a rising edge of controlword bit 7 with the
  drive's other command bits as they were, never 0x0000 on the way, through transition 15 to
  SWITCH ON DISABLED; with bit 7 already high it is lowered first (else there is no edge);
- an ODrive's state comes from its cyclic Heartbeat (the firmware's account): a peer answering a
  remote Heartbeat request with zeros is still shown in its true state, and the table says
  "heartbeat"; with no cyclic heartbeat the tool falls back to the remote request and says so
  (a peer that answers one; the firmware documents remote requests for Get_ messages only).
"""
import itertools

import pytest

from iotad.can import odrive
from iotad.can.frame import Frame
from iotad.cli import main
from simulated_bus_drives import BusDrives

_channels = itertools.count()


def can(bus, *args):
    return main(["can", *args, "--interface", "virtual", "--channel", bus.channel, "--hub-timeout", "0"])


def record_controlwords(drive):
    words = []
    write = drive.write_controlword

    def recorded(word):
        words.append(word)
        write(word)
    drive.write_controlword = recorded
    return words


@pytest.fixture
def drives():
    with BusDrives(f"iotad-can-tools-{next(_channels)}") as bus:
        yield bus


def test_clear_errors_on_an_enabled_cia402_drive_sends_nothing_and_leaves_it_enabled(drives, capsys):
    assert can(drives, "arm", "--node", "5") == 0
    with drives.lock:
        words = record_controlwords(drives.drives[5])
        transitions = list(drives.drives[5].transitions)
    capsys.readouterr()
    assert can(drives, "clear-errors", "--node", "5") == 0
    out = capsys.readouterr().out
    assert "clear-errors: no fault, nothing sent; it reports OPERATION ENABLED (statusword 0x" in out
    with drives.lock:
        assert drives.drives[5].state == "OPERATION ENABLED"
        assert words == [] and drives.drives[5].transitions == transitions


@pytest.mark.parametrize("before", [0x000F, 0x008F], ids=["bit7-low", "bit7-high"])
def test_clear_errors_on_a_faulted_cia402_drive_is_a_rising_edge_of_bit_7_and_transition_15(drives, capsys, before):
    assert can(drives, "arm", "--node", "5") == 0
    with drives.lock:
        drive = drives.drives[5]
        drive.values[(0x6040, 0)] = drive.controlword = before  # what the master last wrote
        drive.fault(0x2310)
        for _ in range(400):  # the fault reaction's ramp ends at once: the motor holds still
            if drive.state == "FAULT":
                break
            drive.update(0.0, 0.0, drive.now + 0.005, 0.005)
        assert drive.state == "FAULT"
        words = record_controlwords(drive)
    assert can(drives, "clear-errors", "--node", "5") == 0
    assert "clear-errors done: SWITCH ON DISABLED, errors: none (statusword 0x" in capsys.readouterr().out
    with drives.lock:
        assert drive.state == "SWITCH ON DISABLED" and drive.transitions[-1] == 15
    assert 0x0000 not in words
    expected = [0x000F, 0x008F] if before & 0x80 else [0x008F]
    assert words == expected


def test_odrive_state_comes_from_its_cyclic_heartbeat_not_a_zero_answer_to_a_remote_request(drives, capsys):
    zero = Frame(odrive.frame_id(1, odrive.COMMANDS["Heartbeat"]), bytes(8))
    with drives.lock:
        axis = drives.axes[1]
        reply = axis.reply
        axis.reply = lambda name: zero if name == "Heartbeat" else reply(name)  # a peer that answers RTR with zeros
    assert can(drives, "scan") == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()]
    assert rows[0][-3:] == ["state", "from", "device"]
    odrive_1 = next(r for r in rows if r[:2] == ["odrive", "1"])
    assert "IDLE" in odrive_1 and "UNDEFINED" not in odrive_1 and odrive_1[-2:] == ["heartbeat", "-"]
    cia = next(r for r in rows if r[:2] == ["cia402", "5"])
    assert "SDO" in cia


def test_without_a_cyclic_heartbeat_the_tools_ask_by_remote_request_and_say_so(capsys):
    """A peer whose cyclic heartbeat is off but that answers a remote Heartbeat request (ODrive's
    firmware documents remote requests for the Get_ messages only; some peers answer this one)."""
    with BusDrives(f"iotad-can-tools-{next(_channels)}", heartbeat_period=0) as quiet:
        with quiet.lock:
            axis = quiet.axes[2]
            handle = axis.handle
            axis.handle = lambda message, now: ([axis.heartbeat()] + handle(message, now)
                                                if message.rtr and message.name == "Heartbeat" else handle(message, now))
        assert can(quiet, "status", "--node", "2", "--protocol", "odrive") == 0
        line = capsys.readouterr().out.splitlines()[1]
        assert "IDLE" in line and line.endswith("remote request  -")
        assert can(quiet, "arm", "--node", "2") == 0
        assert "arm done: CLOSED_LOOP_CONTROL, errors: none (from its remote request)" in capsys.readouterr().out
