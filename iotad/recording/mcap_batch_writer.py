"""The mcap Writer's private fields, used in one place: messages batched into the chunk in
progress, and chunk indexes kept in a temp file rather than in memory.

Checked against mcap 1.6.0 (what `make install` gets). Each use looks its fields up first and,
where one is missing (another mcap version), the caller goes through the Writer's public API
instead: tests/recording/test_mcap_sink.py holds the batch writer to the public API's bytes and
the fallback to a file that reads the same.

Why not the public API alone: `Writer.add_message` builds a Message object and makes five small
writes per message (~6 us); a batch costs one struct.pack and three list appends per message,
5 times as many messages a second (`bench/record.py` prints both).
"""
from __future__ import annotations

import struct
import tempfile
from collections import Counter
from itertools import accumulate
from pathlib import Path
from typing import Any, Iterator

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import Writer


class BatchWriter:
    """`write` and `write_pair` append a message's record bytes and index entries to a batch;
    `commit()` puts the batch into the Writer's chunk in progress at once, keeps the Writer's
    statistics, and lets it close the chunk if it has reached `chunk_size` (so the caller should
    commit every few thousand messages, and before any public Writer call: the file keeps the
    order of the calls). `flush`/`finish` then write the chunk, its indexes and the summary as
    usual. Fields of `mcap.writer.Writer` (1.6.0) it uses: `__chunk_builder` (its
    `record_writer._buffer`, `message_indices`, `num_messages`, `message_start_time`,
    `message_end_time`), `__statistics` and `__maybe_finalize_chunk`."""

    @classmethod
    def of(cls, writer: Writer) -> "BatchWriter | None":
        """A batch writer into `writer`, or None if its private fields are not there."""
        builder = getattr(writer, "_Writer__chunk_builder", None)
        stats = getattr(writer, "_Writer__statistics", None)
        finalize = getattr(writer, "_Writer__maybe_finalize_chunk", None)
        record_writer = getattr(builder, "record_writer", None)
        if builder is None or stats is None or finalize is None or not hasattr(record_writer, "_buffer"):
            return None
        return cls(builder, stats, finalize, record_writer)

    def __init__(self, builder: Any, stats: Any, finalize: Any, record_writer: Any):
        # closures, not methods: the recorder's hot loop calls `write` a million times
        pack = struct.Struct("<BQHIQQ").pack  # opcode, record length, channel, sequence, log, publish
        parts: list[bytes] = []  # header, data, header, data...
        channels: list[int] = []
        logs: list[int] = []
        indices = builder.message_indices
        channel_counts = stats.channel_message_counts
        add_parts, add_channel, add_log = parts.extend, channels.append, logs.append
        add_channels, add_logs = channels.extend, logs.extend

        def write(channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes) -> None:
            add_parts((pack(5, 22 + len(data), channel_id, sequence & 0xFFFFFFFF, log_ns, publish_ns), data))
            add_channel(channel_id)
            add_log(log_ns)

        def write_pair(channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes,
                       channel_id2: int, publish_ns2: int, sequence2: int, data2: bytes) -> None:
            """Two messages with the same log time (a trace event and the message it describes)."""
            add_parts((pack(5, 22 + len(data), channel_id, sequence & 0xFFFFFFFF, log_ns, publish_ns), data,
                       pack(5, 22 + len(data2), channel_id2, sequence2 & 0xFFFFFFFF, log_ns, publish_ns2), data2))
            add_channels((channel_id, channel_id2))
            add_logs((log_ns, log_ns))

        def commit() -> None:
            if not logs:
                return
            buffer = record_writer._buffer  # replaced by a new one after every chunk
            # where each message starts in the chunk: every other running total of the parts
            starts = list(accumulate(map(len, parts), initial=buffer.tell()))[:-1:2]
            buffer.write(b"".join(parts))
            first, last, count = min(logs), max(logs), len(logs)
            appenders = {}  # channel -> its index records' append
            for channel_id, record in zip(channels, zip(logs, starts)):
                try:
                    appenders[channel_id](record)
                except KeyError:
                    index = indices.get(channel_id)
                    if index is None:
                        index = indices[channel_id] = _MessageIndex(channel_id=channel_id, records=[])
                    appenders[channel_id] = index.records.append
                    index.records.append(record)
            for channel_id, n in Counter(channels).items():
                channel_counts[channel_id] += n
            _add_span(builder, "num_messages", first, last, count)  # the chunk's
            _add_span(stats, "message_count", first, last, count)  # the file's
            parts.clear()
            channels.clear()
            logs.clear()
            finalize()  # closes the chunk if it has reached chunk_size

        self.write = write
        self.write_pair = write_pair
        self.commit = commit


def _add_span(counted: Any, count_field: str, first: int, last: int, count: int) -> None:
    """`count` more messages logged from `first` to `last` (ns) in a chunk builder's or the
    Writer's statistics: its message count, start and end time."""
    if getattr(counted, count_field) == 0:
        counted.message_start_time, counted.message_end_time = first, last
    else:
        counted.message_start_time = min(counted.message_start_time, first)
        counted.message_end_time = max(counted.message_end_time, last)
    setattr(counted, count_field, getattr(counted, count_field) + count)


class _SpilledChunkIndexes:
    """Stands in for the mcap Writer's list of chunk indexes: each index is written as its
    record bytes to an unnamed temp file (gone with the process, even after a SIGKILL) and read
    back once, by `Writer.finish`, which writes them into the summary. Iterating yields blocks
    of whole records with the one method the Writer calls on an index, `write(builder)`."""

    BLOCK = 1 << 20

    def __init__(self, folder: Path | None):
        try:
            self._file = tempfile.TemporaryFile(dir=folder, prefix=".iotad-chunk-indexes-")
        except OSError:  # a read-only or odd folder: the system temp dir then
            self._file = tempfile.TemporaryFile(prefix=".iotad-chunk-indexes-")
        self._count = 0

    def append(self, index: Any) -> None:
        builder = RecordBuilder()
        index.write(builder)
        self._file.write(builder.end())
        self._count += 1

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[Any]:
        self._file.flush()
        self._file.seek(0)
        while True:
            block = self._file.read(self.BLOCK)
            if not block:
                break
            yield _RawRecords(block)
        self._file.seek(0, 2)

    def close(self) -> None:
        self._file.close()


class _RawRecords:
    """Record bytes that write themselves into a summary as they are."""

    __slots__ = ("data",)

    def __init__(self, data: bytes):
        self.data = data

    def write(self, builder: Any) -> None:
        builder.write(self.data)


def spill_chunk_indexes(writer: Writer, folder: Path | None) -> _SpilledChunkIndexes | None:
    """Replace the Writer's in-memory chunk index list (a private field of mcap 1.x) by a
    `_SpilledChunkIndexes`; if the field is not there, leave the Writer as it is."""
    if not isinstance(getattr(writer, "_Writer__chunk_indices", None), list):
        return None
    spilled = _SpilledChunkIndexes(folder)
    writer._Writer__chunk_indices = spilled
    return spilled


class _MessageIndex(MessageIndex):
    """The same record, written with one `struct.pack` rather than two small writes per message
    (those cost ~1.5 us a message when a chunk is closed)."""

    def write(self, stream: Any) -> None:
        records = self.records
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write(struct.pack(f"<HI{2 * len(records)}Q", self.channel_id, len(records) * 16,
                                 *[n for record in records for n in record]))
        stream.finish_record()
