"""The simulated CiA 402 drive (sim/cia402_drive.py) takes each transition of the standard's state
diagram it supports (0-16) on the controlword that the profile gives for it, reports each state in
its statusword, and every frame it sends decodes against its EDS."""
import pytest

from iotad.can import canopen as co
from sim.cia402_drive import Cia402Drive
from sim.odrive_axis import AxisConfig

NODE, MASTER = 5, 127
DT = 0.005


class Rig:
    """One drive, a motor that follows its torque as a unit inertia, and a clock."""

    def __init__(self):
        self.drive = Cia402Drive(NODE, AxisConfig(vel_limit=4.0, current_limit=20.0, inertia=0.01))
        self.t, self.pos, self.vel, self.sent = 0.0, 0.0, 0.0, []
        self.tracker = co.PdoTracker([NODE])
        self.collect()

    def collect(self):
        for frame in self.drive.outbox:
            self.tracker.describe(frame)  # raises on a frame its EDS cannot decode
            self.sent.append((self.t, co.decode(frame)))
        self.drive.outbox.clear()

    def frame(self, frame):
        self.tracker.describe(frame)
        self.drive.handle(frame, self.t)
        self.collect()

    def run(self, seconds):
        for _ in range(round(seconds / DT)):
            self.t += DT
            torque = self.drive.update(self.pos, self.vel, self.t, DT)
            self.vel += (torque or 0.0) * DT / 0.01 if torque is not None else -self.vel
            self.pos += self.vel * DT
            self.collect()

    def control(self, word):
        """The controlword by RPDO1, taken at the SYNC after it."""
        od = self.drive.od
        self.frame(co.pack_pdo(od, 0x200 + NODE, co.pdo_map(od, 0x1600), {0x6040: word, 0x607A: round(self.pos * 65536)}))
        self.frame(co.sync())
        self.run(DT)
        return self.drive.state, self.drive.transitions[-1]

    def statuswords(self):
        return [self.drive.od and co.unpack_pdo(self.drive.od, co.pdo_map(self.drive.od, 0x1A00), m.frame.data)[0x6041]
                for _, m in self.sent if m.kind == "TPDO1"]


@pytest.fixture
def rig():
    rig = Rig()
    rig.frame(co.nmt("START", NODE))
    return rig


def test_power_up_is_transitions_0_and_1_with_a_boot_up_message():
    rig = Rig()
    assert rig.drive.transitions == [0, 1] and rig.drive.state == "SWITCH ON DISABLED"
    assert rig.sent[0][1].kind == "HEARTBEAT" and rig.sent[0][1].fields["state"] == "BOOT_UP"
    assert rig.drive.nmt == "PRE_OPERATIONAL"


def test_the_enabling_and_disabling_transitions(rig):
    assert rig.control(co.CW_SHUTDOWN) == ("READY TO SWITCH ON", 2)
    assert rig.control(co.CW_SWITCH_ON) == ("SWITCHED ON", 3)
    assert rig.control(co.CW_ENABLE_OPERATION) == ("OPERATION ENABLED", 4)
    assert rig.control(co.CW_SWITCH_ON) == ("SWITCHED ON", 5)          # disable operation
    assert rig.control(co.CW_SHUTDOWN) == ("READY TO SWITCH ON", 6)
    assert rig.control(co.CW_DISABLE_VOLTAGE) == ("SWITCH ON DISABLED", 7)
    for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
        rig.control(word)
    assert rig.control(co.CW_SHUTDOWN) == ("READY TO SWITCH ON", 8)
    rig.control(co.CW_ENABLE_OPERATION)  # from READY TO SWITCH ON: 3 then 4 at once
    assert rig.drive.transitions[-2:] == [3, 4]
    assert rig.control(co.CW_DISABLE_VOLTAGE) == ("SWITCH ON DISABLED", 9)
    rig.control(co.CW_SHUTDOWN)
    rig.control(co.CW_SWITCH_ON)
    assert rig.control(co.CW_QUICK_STOP) == ("SWITCH ON DISABLED", 10)
    # each state was reported in a TPDO at the SYNC
    states = [co.state_of(word) for word in rig.statuswords()]
    assert {"READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED", "SWITCH ON DISABLED"} <= set(states)


def test_quick_stop_brakes_then_ends_as_its_option_code_says(rig):
    for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
        rig.control(word)
    rig.vel = 2.0  # turning at 2 turns/s when the quick stop comes
    assert rig.control(co.CW_QUICK_STOP) == ("QUICK STOP ACTIVE", 11)
    rig.run(0.5)  # option code 2 (the default): brake on 0x6085, then SWITCH ON DISABLED
    assert rig.drive.state == "SWITCH ON DISABLED" and rig.drive.transitions[-1] == 12
    # option code 6 stays in QUICK STOP ACTIVE, and enable operation goes back (transition 16)
    rig.frame(co.sdo_download(NODE, 0x605A, 0, (6).to_bytes(2, "little")))
    for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
        rig.control(word)
    rig.control(co.CW_QUICK_STOP)
    rig.run(0.5)
    assert rig.drive.state == "QUICK STOP ACTIVE"
    assert rig.control(co.CW_ENABLE_OPERATION) == ("OPERATION ENABLED", 16)
    rig.control(co.CW_QUICK_STOP)
    assert rig.control(co.CW_DISABLE_VOLTAGE) == ("SWITCH ON DISABLED", 12)


def test_a_lost_master_is_a_fault_reaction_then_fault_and_a_reset_clears_it(rig):
    """EMCY 0x8130 at the first step past the consumer time, the fault reaction, PRE-OPERATIONAL."""
    consumer = 0.15
    rig.frame(co.sdo_download(NODE, 0x1016, 1, (MASTER << 16 | round(consumer * 1000)).to_bytes(4, "little")))
    for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
        rig.control(word)
    rig.frame(co.heartbeat(MASTER, "OPERATIONAL"))
    last_beat = rig.t
    rig.run(0.5)
    emcy = [(t, m) for t, m in rig.sent if m.kind == "EMCY"]
    assert emcy[0][1].fields["code"] == 0x8130 and emcy[0][1].fields["name"] == "life guard error or heartbeat error"
    assert consumer < emcy[0][0] - last_beat <= consumer + DT
    assert rig.drive.transitions[-2:] == [13, 14] and rig.drive.state == "FAULT"
    # CiA 301's default error behaviour (0x1029.1 = 0): OPERATIONAL -> PRE-OPERATIONAL, where no
    # PDO is processed: a fault reset by RPDO does nothing until an NMT START
    assert rig.drive.nmt == "PRE_OPERATIONAL"
    assert [m.fields["state"] for _, m in rig.sent if m.kind == "HEARTBEAT"][-1] == "PRE_OPERATIONAL"
    assert rig.control(co.CW_FAULT_RESET) == ("FAULT", 14)
    rig.frame(co.nmt("START", NODE))
    assert rig.control(co.CW_DISABLE_VOLTAGE) == ("FAULT", 14)  # no edge on bit 7 yet
    assert rig.control(co.CW_FAULT_RESET) == ("SWITCH ON DISABLED", 15)
    assert [m.fields["code"] for _, m in rig.sent if m.kind == "EMCY"][-1] == 0x0000  # error reset


def test_the_sdo_server_answers_and_aborts_with_the_cia_301_codes(rig):
    def answer(frame):
        rig.frame(frame)
        return rig.sent[-1][1].fields

    vendor = answer(co.sdo_upload(NODE, 0x1018, 1))
    assert int.from_bytes(vendor["data"], "little") == co.default(rig.drive.od, 0x1018, 1)
    assert answer(co.sdo_upload(NODE, 0x1234, 0))["code"] == 0x06020000        # no such object
    assert answer(co.sdo_upload(NODE, 0x1018, 9))["code"] == 0x06090011        # no such subindex
    assert answer(co.sdo_download(NODE, 0x6041, 0, b"\0\0"))["code"] == 0x06010002   # read only
    assert answer(co.sdo_download(NODE, 0x6060, 0, b"\x08\0"))["code"] == 0x06070010  # wrong length
    assert answer(co.sdo_download(NODE, 0x6060, 0, b"\x03"))["code"] == 0x06090030   # a mode it lacks
    assert answer(co.sdo_download(NODE, 0x1600, 1, (0x60FF0020).to_bytes(4, "little")))["code"] == 0x06010000
    assert answer(co.sdo_download(NODE, 0x6060, 0, b"\x09"))["service"] == "download"  # CSV: accepted
    assert rig.drive.read(0x6061) == 9


def test_profile_position_moves_at_a_new_set_point(rig):
    rig.frame(co.sdo_download(NODE, 0x6060, 0, b"\x01"))
    for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
        rig.control(word)
    od = rig.drive.od
    rpdo = co.pdo_map(od, 0x1600)
    rig.frame(co.pack_pdo(od, 0x200 + NODE, rpdo, {0x6040: 0x3F, 0x607A: 65536}))  # one turn, bit 4 up
    rig.frame(co.sync())
    rig.run(0.01)
    assert rig.drive.statusword & co.SW_SETPOINT_ACK
    rig.frame(co.pack_pdo(od, 0x200 + NODE, rpdo, {0x6040: 0x2F, 0x607A: 65536}))
    rig.frame(co.sync())
    rig.run(3.0)
    assert rig.pos == pytest.approx(1.0, abs=0.01)
    assert rig.drive.statusword & co.SW_TARGET_REACHED
