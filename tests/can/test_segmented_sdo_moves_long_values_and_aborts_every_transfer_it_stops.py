"""SDO as CiA 301 has it, between `iotad.can.bringup` (the client) and the simulated CiA 402 drive
(the server), on an in-process bus:

- a value over 4 bytes (the device name 0x1008, the versions 0x1009/0x100A, a string object of
  the EDS) goes by segmented upload and download, 7 bytes a segment, the toggle bit alternating;
- a segmented upload the server stops answering is ended by the client with an SDO abort
  0x05040000 (timeout) for that object, as seen on the bus; so is a write nobody answers;
- a segment with the wrong toggle bit is aborted by the server with 0x05030000.
"""
import itertools
import time

from iotad.can import bringup
from iotad.can import canopen as co
from iotad.can.bus import open_bus
from sim.cia402_drive import Cia402Drive
from simulated_bus_drives import BusDrives

_channels = itertools.count()


def sniffed(channel):
    """Every frame on the channel after a moment: a second station on the bus."""
    return open_bus("virtual", channel)


def frames_of(bus, seconds=0.2):
    out, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        got = bus.recv_frame(timeout=0.02)
        if got is not None:
            out.append(got[1])
    return out


def test_long_strings_go_by_segments_both_ways():
    with BusDrives(f"iotad-sdo-{next(_channels)}", odrives=(), cia402=(5,)) as drives:
        with open_bus("virtual", drives.channel) as bus:
            link = bringup.Link(bus)
            read = bringup.sdo_read(link, [5], 0x1008)[5]
            assert read["data"] == b"iotad simulated CiA 402 drive" and read["size"] == 29
            assert bringup.sdo_read(link, [5], 0x100A)[5]["data"] == b"iotad-drive 0.2.0"
            bringup.sdo_write(link, 5, 0x2002, 0, b"left elbow joint")   # 16 bytes: three segments
            with drives.lock:
                assert drives.drives[5].values[(0x2002, 0)] == "left elbow joint"
            assert bringup.sdo_read(link, [5], 0x2002)[5]["data"] == b"left elbow joint"
            bringup.sdo_write(link, 5, 0x2002, 0, b"arm")                # short: expedited
            assert bringup.sdo_read(link, [5], 0x2002)[5]["data"] == b"arm"


def test_a_segmented_upload_that_stops_answering_is_aborted_on_the_bus():
    with BusDrives(f"iotad-sdo-{next(_channels)}", odrives=(), cia402=(5,)) as drives:
        with drives.lock:
            drive = drives.drives[5]
            handle = drive.handle

            def silent(frame, now):
                message = co.decode(frame)
                if message.kind == "SDO_REQUEST" and message.fields["service"] == "upload_segment":
                    return None  # the server falls silent after the initiate
                return handle(frame, now)
            drive.handle = silent
        with open_bus("virtual", drives.channel) as bus, sniffed(drives.channel) as sniffer:
            link = bringup.Link(bus, timeout=0.1)
            assert bringup.sdo_read(link, [5], 0x100A) == {}
            aborts = [co.decode(f).fields for f in frames_of(sniffer)
                      if f.id == co.RSDO + 5 and co.decode(f).fields["service"] == "abort"]
        assert [(a["index"], a["subindex"], a["code"]) for a in aborts] == [(0x100A, 0, 0x05040000)]
        with drives.lock:
            assert drive.transfer is None  # the client's abort ended the transfer on the server too


def test_a_write_nobody_answers_is_aborted_and_a_clear_failure():
    channel = f"iotad-sdo-{next(_channels)}"
    with open_bus("virtual", channel) as bus, sniffed(channel) as sniffer:
        link = bringup.Link(bus, timeout=0.05)
        try:
            bringup.sdo_write(link, 9, 0x2002, 0, b"nobody home")
        except bringup.CommandFailed as exc:
            assert "no answer to the SDO write of 0x2002.00 within 0.05 s (aborted)" in str(exc)
        else:
            raise AssertionError("a write nobody answered succeeded")
        aborts = [co.decode(f).fields for f in frames_of(sniffer) if f.id == co.RSDO + 9]
        assert [(a["service"], a.get("code")) for a in aborts][-1] == ("abort", 0x05040000)


def test_a_segment_with_the_wrong_toggle_bit_is_aborted_by_the_server():
    drive = Cia402Drive(5)
    drive.outbox.clear()
    drive.handle(co.sdo_upload(5, 0x1008, 0), 0.0)
    assert co.decode(drive.outbox[-1]).fields == {"service": "upload", "index": 0x1008, "subindex": 0,
                                                  "segmented": True, "size": 29}
    drive.handle(co.sdo_upload_segment_request(5, 0), 0.0)
    assert co.decode(drive.outbox[-1]).fields["data"] == b"iotad s"
    drive.handle(co.sdo_upload_segment_request(5, 0), 0.0)  # toggle 0 again: should be 1
    answer = co.decode(drive.outbox[-1]).fields
    assert (answer["service"], answer["index"], answer["code"]) == ("abort", 0x1008, 0x05030000)
    assert drive.transfer is None
