"""The delivery check of a long recording fits in memory: of each message it matches it keeps a
compact record (its times, its value packed as msgpack), decodes a value only to compare two
that differ byte for byte or to print one, and never holds the recording's messages decoded. So
what it takes grows with the recording by much less than a decoded copy of the recording would
(the check that held every trace event and wire value decoded took 1.4 times that)."""
import tracemalloc
from pathlib import Path

from iotad.cli import main
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]


def peak(work) -> tuple[int, object]:
    """(the most bytes allocated at once while `work()` ran, beyond what was before; its result)."""
    tracemalloc.start()
    try:
        result = work()
        return tracemalloc.get_traced_memory()[1], result
    finally:
        tracemalloc.stop()


def costs(directory: Path, until: str) -> tuple[int, int]:
    """(bytes of the recording's messages held decoded, bytes the delivery check takes) of a
    virtual run of the conveyor until `until`."""
    out = directory / f"conveyor-{until}.mcap"
    assert main(["run", str(ROOT / "examples" / "conveyor.toml"), "--virtual", "--until", until,
                 "-o", str(out), "--plain"]) == 0
    recording = read_recording(out)
    decoded, messages = peak(lambda: [m.value for m in recording.messages])
    del messages
    checked, report = peak(lambda: check_delivery(recording))
    # the check did its work: every binding and the CAN bus, every message delivered as sent
    assert report.checked and report.ok and any(link.kind == "can" for link in report.links)
    assert report.totals()["delivered"] > 1000
    return decoded, checked


def test_the_check_of_a_run_twice_as_long_grows_by_much_less_than_its_messages_decoded(tmp_path):
    decoded_short, checked_short = costs(tmp_path, "3")
    decoded_long, checked_long = costs(tmp_path, "6")
    assert decoded_long > 1.8 * decoded_short  # twice the messages, near enough
    # fixed costs (the specs, the system file) cancel out in the differences
    assert checked_long - checked_short < 0.75 * (decoded_long - decoded_short)
