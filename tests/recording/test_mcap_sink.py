"""McapSink's fast writer (the recorder's hot path): batched messages, pairs and plain writes in
order, with chunk indexes, message indexes and statistics the mcap readers accept; the same bytes
as the mcap Writer's public API, and that API where the Writer's private fields are not there."""
import struct


import zstandard
from mcap.reader import make_reader
from mcap.records import Chunk, MessageIndex
from mcap.stream_reader import StreamReader

from iotad.recording import mcap_sink
from iotad.recording.mcap_batch_writer import BatchWriter
from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink


def test_fast_writer_batches_pairs_and_plain_writes_into_a_valid_indexed_file(tmp_path):
    path = tmp_path / "fast.mcap"
    sink = McapSink(path, chunk_size=4096)  # small chunks: several close in a batch's wake
    trace = sink.channel("iota/s/n/@trace", "trace", {})
    out = sink.channel("iota/s/n/out", "out", {})
    write = sink.fast_writer()
    expected = []
    for k in range(500):
        log = 1_000 + k
        if k % 3 == 0:
            sink.write_pair(trace, log, log - 5, k, packb({"k": k}), out, log - 7, k, packb(k))
            expected += [("iota/s/n/@trace", log, log - 5, k, packb({"k": k})), ("iota/s/n/out", log, log - 7, k, packb(k))]
        elif k % 3 == 1:
            write(out, log, log - 1, k, packb(k))
            expected.append(("iota/s/n/out", log, log - 1, k, packb(k)))
        else:
            sink.write(trace, log, log, k, packb("plain"))  # after what the fast writer holds
            expected.append(("iota/s/n/@trace", log, log, k, packb("plain")))
        if k == 250:
            sink.flush()
    sink.finish()

    recording = read_recording(path)
    assert recording.complete
    assert [(m.topic, m.log_time, m.publish_time, m.sequence, m.data) for m in recording.messages] == expected
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(expected)
        assert summary.statistics.message_start_time == 1_000
        assert summary.statistics.message_end_time == 1_499
        assert sum(summary.statistics.channel_message_counts.values()) == len(expected)
        assert len(summary.chunk_indexes) > 2
        # the indexed reader finds every message through chunk and message indexes, in log order
        got = [(channel.topic, message.log_time, message.data) for _, channel, message in reader.iter_messages()]
    assert sorted(got) == sorted((t, log, data) for t, log, _, _, data in expected)

    # every message index entry points at a message record of its channel and log time in its chunk
    checked = 0
    with open(path, "rb") as stream:
        chunk = None
        for record in StreamReader(stream, emit_chunks=True, validate_crcs=True).records:
            if isinstance(record, Chunk):
                chunk = zstandard.ZstdDecompressor().decompress(record.data, max_output_size=record.uncompressed_size)
            elif isinstance(record, MessageIndex):
                for log, offset in record.records:
                    opcode, _, channel_id, _, log_time = struct.unpack_from("<BQHIQ", chunk, offset)
                    assert (opcode, channel_id, log_time) == (5, record.channel_id, log)
                    checked += 1
    assert checked == len(expected)


def write_messages(path, fast: bool) -> None:
    """600 messages on three channels, pairs among them, flushed every 100, through the batch
    writer or through the mcap Writer's public `add_message`."""
    sink = McapSink(path)
    channels = [sink.channel(f"iota/s/n{k}/out", f"t{k}", {"type": "integer"}) for k in range(3)]
    write = sink.fast_writer() if fast else sink.write
    write_pair = sink.write_pair
    for k in range(600):
        log = 5_000 + 10 * k
        if k % 5 == 0:
            write_pair(channels[0], log, log - 3, k, packb({"k": k}), channels[2], log - 4, k, packb(-k))
        else:
            write(channels[k % 3], log, log - 1, k, packb(k))
        if k % 100 == 99:
            sink.flush()
    sink.finish()


def test_the_batch_writer_writes_the_bytes_of_the_public_api(tmp_path):
    write_messages(tmp_path / "fast.mcap", fast=True)
    write_messages(tmp_path / "public.mcap", fast=False)
    assert (tmp_path / "fast.mcap").read_bytes() == (tmp_path / "public.mcap").read_bytes()
    assert len(read_recording(tmp_path / "fast.mcap").messages) == 720


def test_without_the_writers_private_fields_the_sink_writes_through_the_public_api(tmp_path, monkeypatch):
    assert BatchWriter.of(object()) is None  # a Writer without them (another mcap version)
    write_messages(tmp_path / "public.mcap", fast=False)
    monkeypatch.setattr(mcap_sink.BatchWriter, "of", classmethod(lambda cls, writer: None))
    sink = McapSink(tmp_path / "x.mcap")
    assert sink.fast_writer() == sink.write and sink.write_pair == sink._write_pair
    sink.finish()
    write_messages(tmp_path / "fallback.mcap", fast=True)
    assert (tmp_path / "fallback.mcap").read_bytes() == (tmp_path / "public.mcap").read_bytes()
