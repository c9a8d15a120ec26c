"""Malformed or unexpected CANopen frames from a CiA 402 drive's ids (wrong lengths, a remote frame,
another master's RPDO, SDO or SYNC, a TPDO nobody mapped) are bad_frame reports with a reason and
change nothing; an SDO abort during the start-up and an EMCY are joint_status events naming their
codes; the node goes on (it arms when the drive answers again). Nothing a frame carries crashes it."""
import pytest
from hypothesis import given, settings, strategies as st

from iotad.can import canopen as co
from iotad.can.frame import Frame
from motor_bench import Bench

JOINTS = [{"name": "a", "node_id": 3, "protocol": "cia402"}, {"name": "b", "node_id": 2}]  # a CiA 402 drive, an ODrive
OD = co.object_dictionary(node_id=3)


def frame(ident, data=b"", rtr=False, dlc=None):
    value = Frame(ident, bytes(data), rtr=rtr).to_value() if not rtr else Frame.remote(ident, dlc or 0).to_value()
    if dlc is not None and not rtr:
        value["dlc"] = dlc
    return value


BAD = [
    ("WRONG_DLC", frame(0x703, b"\x05\x00")),                       # heartbeat of 2 bytes
    ("WRONG_DLC", frame(0x083, b"\x30\x81\x11")),                   # EMCY of 3 bytes
    ("WRONG_DLC", frame(0x583, bytes(5))),                          # SDO response of 5 bytes
    ("WRONG_DLC", frame(0x183, bytes(5))),                          # TPDO1 shorter than its mapping
    ("WRONG_DLC", frame(0x703, rtr=True, dlc=1)),                   # a remote request of a heartbeat
    ("BAD_VALUE", frame(0x703, b"\x63")),                           # heartbeat state 99: no NMT state
    ("UNEXPECTED", frame(0x203, bytes(6))),                         # someone's RPDO to our drive
    ("UNEXPECTED", frame(0x603, co.sdo_upload(3, 0x1000, 0).data)),  # someone's SDO request
    ("UNEXPECTED", frame(0x080)),                                   # another master's SYNC
    ("UNEXPECTED", frame(0x000, b"\x01\x03")),                      # another master's NMT start
    ("UNKNOWN_COMMAND", frame(0x383, bytes(8))),                    # TPDO3: not mapped here
]


@pytest.fixture
def bench():
    return Bench(joints=JOINTS)


def test_each_bad_canopen_frame_is_reported_with_its_reason(bench):
    for k, (_, value) in enumerate(BAD):
        bench.hear(0.01 + 0.001 * k, value)
    bench.run(0.1)
    reports = [(e["value"]["reason"], Frame.from_value(e["value"]["frame"])) for e in bench.events("bad_frame")]
    assert reports == [(reason, Frame.from_value(value)) for reason, value in BAD]
    assert not bench.violations()


def answer_the_scaling_reads(bench, rated_mnm=1000):
    """The start-up's first SDOs read the drive's scaling (0x6076, 0x608F, 0x6091, 0x6092): answer
    them as a drive with only 0x6076 and 0x608F would, one at a time; the first write follows."""
    t = 0.001
    while True:
        bench.run(t)
        (last,) = [data for _, ident, _, data in bench.sent() if ident == 0x603][-1:]
        fields = co.decode(Frame(0x603, last)).fields
        if fields["service"] != "upload":
            return t, fields
        index, sub = fields["index"], fields["subindex"]
        values = {(0x6076, 0): rated_mnm, (0x608F, 1): 65536, (0x608F, 2): 1}
        t += 0.001
        if (index, sub) in values:
            answer = co.sdo_upload_response(3, index, sub, values[(index, sub)].to_bytes(4, "little"))
        else:
            answer = co.sdo_abort(3, index, sub, 0x06020000)
        bench.hear(t, answer.to_value())


def test_an_sdo_abort_in_the_start_up_is_an_event_with_its_code_and_a_retry(bench):
    t, fields = answer_the_scaling_reads(bench)
    assert fields["service"] == "download", "the start-up's first SDO write went out"
    index, sub = fields["index"], fields["subindex"]
    bench.hear(0.01, co.sdo_abort(3, index, sub, 0x06090030).to_value())
    for k in range(7):  # the drive's heartbeat goes on (a LOST drive is not armed)
        bench.hear(0.05 + 0.1 * k, co.heartbeat(3, "PRE_OPERATIONAL").to_value())
    bench.run(0.6)
    aborts = bench.status(0, "SDO_ABORT")
    assert len(aborts) == 1 and aborts[0]["disarm_reason"] == 0x06090030 and aborts[0]["phase"] == "UNARMED"
    retries = [t for t, ident, _, data in bench.sent(since=0.02) if ident == 0x603]
    assert retries and retries[0] >= 0.01 + 0.5  # again after arm_retry
    assert not bench.violations()


def test_an_emcy_is_an_event_with_its_code(bench):
    bench.hear(0.02, co.emcy(3, 0x2310, 0x03).to_value())
    bench.run(0.05)
    emcy = bench.status(0, "EMCY")
    assert len(emcy) == 1 and emcy[0]["axis_error"] == 0x2310
    (violation,) = bench.violations()  # and by name (test_every_emcy_is_a_recorded_violation_...)
    assert violation["value"]["name"] == "continuous over-current"


@settings(max_examples=150, deadline=None)
@given(ident=st.sampled_from([0x083, 0x183, 0x283, 0x583, 0x703, 0x383, 0x203, 0x603, 0x000, 0x080, 0x043]),
       data=st.binary(max_size=8), rtr=st.booleans())
def test_no_frame_on_a_drives_ids_crashes_the_node(ident, data, rtr):
    bench = Bench(joints=JOINTS)
    value = Frame.remote(ident, len(data)).to_value() if rtr else Frame(ident, data).to_value()
    bench.hear(0.01, value)
    bench.run(0.03)
    # a well-formed EMCY is a recorded drive_emcy (by name); nothing else, and never a runtime_error
    assert [v["value"]["violation"] for v in bench.violations()] == (
        ["drive_emcy"] if ident == 0x083 and len(data) == 8 and not rtr else [])
    assert len(bench.events("can_rx", kind="input")) == 1
