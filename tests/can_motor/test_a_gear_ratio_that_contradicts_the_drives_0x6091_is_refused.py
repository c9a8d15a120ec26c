"""A CiA 402 drive's gear ratio (0x6091: motor revolutions per driving shaft revolution), read at
start-up, against the joint table's `gear_ratio` (motor turns per joint turn): a table that states
another is refused with one line and SCALE_MISMATCH (disarm_reason 0x6091, requested the table's,
applied the drive's), FAULT, never configured; one that states the same goes on; one that states
none takes the drive's, so that no position or effort is scaled by a ratio the drive did not give
(seen on the bus: the velocity limit 0x607F the node writes is in the drive's units through it)."""
import math

import pytest

from iotad.can import canopen as co
from iotad.can.frame import Frame
from motor_bench import Bench

DRIVE = {(0x6076, 0): 1000, (0x608F, 1): 65536, (0x608F, 2): 1, (0x6091, 1): 10, (0x6091, 2): 1}


def start_up(bench, values=DRIVE, until=0.3):
    """Answer every SDO of drive 3's start-up as a drive with `values` (0x6092 absent) would; the
    writes are answered as accepted. Returns the writes as {(index, sub): value}."""
    t, answered, writes = 0.001, 0, {}
    while t < until:
        bench.run(t)
        requests = [data for _, ident, _, data in bench.sent() if ident == 0x603]
        for data in requests[answered:]:
            fields = co.decode(Frame(0x603, data)).fields
            index, sub = fields["index"], fields["subindex"]
            if fields["service"] == "upload":
                answer = (co.sdo_upload_response(3, index, sub, values[(index, sub)].to_bytes(4, "little"))
                          if (index, sub) in values else co.sdo_abort(3, index, sub, 0x06020000))
            else:
                writes[(index, sub)] = int.from_bytes(fields["data"], "little")
                answer = co.sdo_download_response(3, index, sub)
            bench.hear(t + 0.0005, answer.to_value())
        answered = len(requests)
        t += 0.002
    return writes


def joints(**table):
    return [dict({"name": "wrist", "node_id": 3, "protocol": "cia402"}, **table)]


def test_a_table_gear_ratio_that_contradicts_the_drives_is_refused_with_one_line(capfd):
    bench = Bench(joints=joints(gear_ratio=9.0))
    writes = start_up(bench)
    (mismatch,) = bench.status(0, "SCALE_MISMATCH")
    assert (mismatch["disarm_reason"], mismatch["requested"], mismatch["applied"], mismatch["phase"]) == (
        0x6091, 9.0, 10.0, "FAULT")
    assert writes == {}  # never configured, never started
    assert not bench.status(0, "ARM_DONE") and bench.motor.axes[0].phase == "FAULT"
    lines = [line for line in capfd.readouterr().err.splitlines() if "contradicts" in line]
    assert lines == ["CanMotor: joint wrist: the joint table's gear_ratio = 9 contradicts the drive's gear ratio "
                     "(0x6091, motor revolutions per shaft revolution) = 10; not armed (fix the table or the drive)"]


@pytest.mark.parametrize("table", [{"gear_ratio": 10.0}, {}], ids=["the-same", "none-stated"])
def test_a_table_that_agrees_or_states_none_is_scaled_by_the_drives_gear_ratio(table):
    bench = Bench(joints=joints(**table))
    writes = start_up(bench)
    assert not bench.status(0, "SCALE_MISMATCH")
    assert bench.motor.links[0].joint.gear_ratio == 10.0
    # velocity_limit (default pi rad/s at the joint) in increments/s: 10 motor turns per joint turn
    assert writes[(0x607F, 0)] == round(10.0 * math.pi / (2 * math.pi) * 65536)


def test_a_drive_without_0x6091_leaves_the_tables_gear_ratio():
    bench = Bench(joints=joints(gear_ratio=9.0))
    values = {k: v for k, v in DRIVE.items() if k[0] != 0x6091}
    writes = start_up(bench, values)
    assert not bench.status(0, "SCALE_MISMATCH")
    assert writes[(0x607F, 0)] == round(9.0 * 0.5 * 65536)
