"""MCAP written in livedic's chunk layout, on the ``mcap`` library: ``ChunkedWriter`` and the header's ``library_name``.

``ChunkedWriter`` writes what an ``mcap.writer.Writer`` would, with chunks livedic closes (and writes) itself,
keeping images and data in chunks of their own (see its notes); ``acquire.recording.writer`` writes live
sessions with it and ``acquire.recording.recover`` rewrites damaged ones.
"""

from __future__ import annotations

import io
import struct
import time
import zlib
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import IO, Any

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Channel, ChunkIndex, McapRecord, MessageIndex, Schema
from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, IndexType, Writer

from livedic.acquire.recording.container import MESSAGE_HEADER_BYTES

__all__ = ["ChunkedWriter", "library_name", "software_version"]

_BytesLike = bytes | bytearray | memoryview      # a payload or a part of one


def software_version() -> str:
    """The installed livedic version, or "unknown"."""
    try:
        from importlib.metadata import version
        return version("livedic")
    except Exception:  # noqa: BLE001 - metadata is best effort
        return "unknown"


def library_name(how: str = "") -> str:
    """The MCAP header's ``library``: livedic's version, ``how`` it was written (e.g. "recovered"), mcap's."""
    return f"livedic/{software_version()} {f'({how}) ' if how else ''}{LIBRARY_IDENTIFIER}"


_NEVER = 1 << 62                 # mcap's own size-triggered chunking is switched off
_MESSAGE_HEAD = struct.Struct("<BQHIQQ")    # a Message record up to its data: opcode, length, channel, sequence,
                                            # log time, publish time (mcap.records.Message.write's layout)
_CHUNK_HEAD = struct.Struct("<BQQQQI")      # a Chunk record: opcode, length, start, end, uncompressed size, CRC;
_CHUNK_FIELDS = 8 + 8 + 8 + 4 + 4 + 8       # then its compression (a u32-prefixed string) and data length (u64)


class _ChunkRecords:
    """The records of one chunk, laid out as mcap's ``ChunkBuilder`` lays them out, in a buffer kept for the next.

    Why not mcap's builder: it copies each payload into a ``BytesIO``, then the whole chunk twice more on its
    way to the file, all of it holding the GIL: ~1.1 ms a 1 MP frame, ~2.3 ms at once when an image chunk
    is written, up to ~6.6 ms for a data chunk, time in which the tracking thread cannot run (measured:
    ``docs/guide/performance.md``, "Recording"). Here a payload is copied once, by numpy, which lets the GIL
    go for large copies, into a buffer that is reused (no fresh pages to fault in); ``ChunkedWriter`` writes
    it out with calls that let the GIL go too.
    """

    def __init__(self) -> None:
        self.buffer = np.empty(0, np.uint8)
        self.reset()

    def reset(self) -> None:
        self.size = 0
        self.num_messages = 0
        self.start_time = self.end_time = 0
        # channel id -> [(log_time, offset in the chunk)], in order of first use
        self.indexes: dict[int, list[tuple[int, int]]] = {}

    def view(self) -> memoryview:
        return self.buffer.data[:self.size]

    def append(self, data: _BytesLike) -> None:
        """Copy the bytes-like ``data`` to the end."""
        octets = np.frombuffer(data, np.uint8)
        end = self.size + octets.size
        if end > self.buffer.size:
            grown = np.empty(max(end, 2 * self.buffer.size), np.uint8)
            grown[:self.size] = self.buffer[:self.size]
            self.buffer = grown
        self.buffer[self.size:end] = octets
        self.size = end

    def add_message(self, channel_id: int, log_time: int, publish_time: int, sequence: int,
                    parts: Sequence[_BytesLike]) -> None:
        """A Message record whose data is the concatenation of ``parts`` (bytes-like, 1-D)."""
        length = sum(memoryview(part).nbytes for part in parts)
        offset = self.size
        self.append(_MESSAGE_HEAD.pack(Opcode.MESSAGE, MESSAGE_HEADER_BYTES + length, channel_id, sequence, log_time,
                                       publish_time))
        for part in parts:
            self.append(part)
        self.start_time = log_time if self.num_messages == 0 else min(self.start_time, log_time)
        self.end_time = max(self.end_time, log_time)
        self.indexes.setdefault(channel_id, []).append((log_time, offset))
        self.num_messages += 1


class _SummaryWriter(Writer):
    """mcap's ``Writer`` for everything but the chunks: header, metadata, schemas, channels, summary, footer.

    ``ChunkedWriter`` writes the chunks itself and hands each one's ``ChunkIndex`` and message counts to
    ``add_chunk``, which adds them where mcap's own chunks go, so that ``finish`` writes the same summary
    (statistics, chunk indexes) as for chunks mcap wrote. mcap has no public call for this: ``add_chunk``
    updates the writer's private statistics and chunk index list. The test that writes the same messages
    with a plain ``mcap.writer.Writer`` and compares the files byte for byte is what guards it against a
    change of mcap. Each schema and channel record is also handed to ``on_record`` as it is registered: a
    chunked mcap file carries them in its next chunk.
    """

    def __init__(self, stream: IO[bytes], on_record: Callable[[McapRecord], None], **options: Any) -> None:
        super().__init__(stream, **options)
        self._on_record = on_record
        self._statistics = getattr(self, "_Writer__statistics")
        self._chunk_indices: list[ChunkIndex] = getattr(self, "_Writer__chunk_indices")

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema_id = super().register_schema(name, encoding, data)
        self._on_record(Schema(id=schema_id, data=data, encoding=encoding, name=name))
        return schema_id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] = {}) -> int:  # noqa: B006 - mcap's signature
        channel_id = super().register_channel(topic, message_encoding, schema_id, metadata)
        self._on_record(Channel(id=channel_id, topic=topic, message_encoding=message_encoding,
                                schema_id=schema_id, metadata=metadata))
        return channel_id

    def add_message(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("a ChunkedWriter's messages go through ChunkedWriter.add")

    def add_chunk(self, chunk_index: ChunkIndex, records: _ChunkRecords) -> None:
        """Count the chunk ``chunk_index`` (written at its offset) and its ``_ChunkRecords``' messages."""
        stats = self._statistics
        if stats.message_count == 0:
            stats.message_start_time = records.start_time
        else:
            stats.message_start_time = min(stats.message_start_time, records.start_time)
        stats.message_end_time = max(stats.message_end_time, records.end_time)
        for channel_id, entries in records.indexes.items():
            stats.channel_message_counts[channel_id] += len(entries)
        stats.message_count += records.num_messages
        stats.chunk_count += 1
        self._chunk_indices.append(chunk_index)


class ChunkedWriter:
    """An MCAP file written in livedic's chunk layout: the bytes mcap's ``Writer`` would write, chunk by chunk.

    Messages are added with a ``kind``: "image" (``/camera/image`` and
    ``/camera/frame_info``) or "data" (results, events, the session message). A chunk
    holds one kind only, so an indexed reader fetches the results without reading any
    image. The open image chunk plays the part of mcap's single open chunk (schema and
    channel records registered go into it, as mcap puts them); data messages wait in a
    chunk of their own and are written together as one data chunk. So images and
    results that alternate every frame no longer cost a chunk each: the writer keeps a
    ~570-byte ``ChunkIndex`` per chunk in memory until ``finish`` (for the summary),
    which is what grew the memory of long sessions when every frame made two chunks.

    When things are written:

    * the image chunk is closed when it holds ``chunk_bytes``;
    * the pending data is written as one chunk when it holds ``chunk_bytes``; the
      open image chunk is closed first (its frames come before their results in the
      file);
    * when the oldest unwritten message, image or data, is ``flush_interval_s`` old,
      both are written (``flush_due``, called on every write by the ``Recorder`` and
      by its background thread): one age check for both keeps them in step, where two
      independent timers would each cut the other's chunk short;
    * ``flush`` and ``finish`` write everything.

    Pending data is *not* written each time an image chunk fills up
    (``data_with_images=False``, the default). Measured at 1 MP Mono8, 50 fps, 1,000
    points (85 KB of results a frame) with 4 MiB chunks: 0.385 chunks a frame,
    against 0.50 when the data follows every image chunk (one image chunk per 4
    frames); with 1 MiB chunks 1.08 against 2.0. The price is that results may lag
    their frames in the file by up to ``flush_interval_s``, which the age check
    bounds anyway. At 512x512 (age-bound) both give 0.15.

    Chunk size (``Recorder``'s default ``chunk_bytes``, 4 MiB), measured at 1 MP, 50
    fps, 1,000 points on 2 shared cores with mcap's own chunk writer: 1 / 4 / 8 / 16
    MiB give 1.08 / 0.385 / 0.23 / 0.15 chunks a frame (~110 / 40 / 24 / 16 MB of
    chunk indexes an hour), a transient peak of ~3 / 12 / 19 / 37 MB while a chunk is
    written, a ``write_frame`` p99 of ~3 / 9 / 16 / 37 ms (the call that writes the
    chunk; the frame period is 20 ms) and ~420 / 445 / 500 / ~325 MB/s of write
    throughput (median of 3, one run for 16 MiB; noisy). 4 MiB takes most of the gain
    while the burst stays under half a frame period; at 512x512 chunks are closed by
    age from 4 MiB on, so larger ones gain nothing there.

    How a chunk is written. Each message record is copied once into a buffer kept
    from chunk to chunk (``_ChunkRecords``); a chunk is written as its header, the
    buffer (one ``write``, which lets the GIL go while the kernel copies it; the CRC
    is ``zlib.crc32``, which lets it go too) and its message indexes (mcap's
    ``MessageIndex`` records); its ``ChunkIndex`` goes to mcap's writer, which writes
    everything else (``_SummaryWriter``). The bytes are those of ``mcap.writer.Writer``
    given the same messages and flushed where the chunks end (a test compares them).

    ``chunks_written`` counts the chunks written; ``durable_counts`` counts, by the
    ``count_as`` label given to ``add``, the messages in written chunks (handed to the
    kernel: they survive the death of the process). Not thread safe: the ``Recorder``
    calls it under its lock. Also used by ``acquire.recording.recover`` (which gives
    no ``flush_interval_s``: size and ``finish`` only).
    """

    def __init__(self, stream: IO[bytes], *, chunk_bytes: int, compression: str | None, library: str,
                 flush_interval_s: float | None = None, data_with_images: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        codec = {None: CompressionType.NONE, "lz4": CompressionType.LZ4, "zstd": CompressionType.ZSTD}
        if isinstance(stream, io.RawIOBase):
            stream = io.BufferedWriter(stream)   # as mcap's writer would: then both write to the same buffer
        self.stream: IO[bytes] = stream
        self.compression = compression or ""
        self._open = _ChunkRecords()         # mcap's open chunk: image messages, schema and channel records
        self._data = _ChunkRecords()         # the data messages waiting
        self.writer = _SummaryWriter(stream, self._add_record, chunk_size=_NEVER, compression=codec[compression],
                                     index_types=IndexType.ALL, use_chunking=True, enable_crcs=True)
        self.writer.start(profile="", library=library)
        self.chunk_bytes = int(chunk_bytes)
        self.flush_interval_s = flush_interval_s
        self.data_with_images = bool(data_with_images)
        self.clock = clock                   # seconds, monotonic (a test may drive it by hand)
        self.image_bytes = 0                 # the open image chunk's messages
        self.image_since: float | None = None    # monotonic time of its first message; None: no open chunk
        self.image_counts: Counter[str] = Counter()
        self.pending_bytes = 0               # the data waiting
        self.pending_since: float | None = None
        self.pending_counts: Counter[str] = Counter()
        self.durable_counts: Counter[str] = Counter()
        self.chunks_written = 0
        self._schemas: dict[tuple[str, str, bytes], int] = {}

    def chunk_indexes(self) -> list[ChunkIndex]:
        """The chunk indexes mcap's writer holds in memory until ``finish`` writes the summary (a diagnostic:
        ``livedic bench soak`` sizes it)."""
        return self.writer._chunk_indices

    def register(self, topic: str, schema_name: str, schema_data: bytes, *, schema_encoding: str = "protobuf",
                 message_encoding: str = "protobuf", metadata: Mapping[str, str] | None = None) -> int:
        key = (schema_name, schema_encoding, schema_data)
        schema_id = self._schemas.get(key)
        if schema_id is None:
            schema_id = self.writer.register_schema(schema_name, schema_encoding, schema_data)
            self._schemas[key] = schema_id
        return self.writer.register_channel(topic, message_encoding, schema_id, dict(metadata or {}))

    def add(self, kind: str, channel_id: int, log_time: int,
            data: _BytesLike | tuple[_BytesLike, ...] | list[_BytesLike], *,
            publish_time: int = 0, sequence: int = 0, count_as: str | None = None) -> None:
        """Add one message of ``kind`` ("image" or "data"); writes a chunk when one is full.

        ``data`` is the payload, bytes-like, or a tuple (or list) of bytes-like parts whose concatenation
        is the payload (e.g. a header and an image's pixels, which are then copied only once). It is
        copied here: the caller may reuse its buffers once ``add`` returns.
        """
        parts: tuple[_BytesLike, ...] = tuple(data) if isinstance(data, (tuple, list)) else (data,)
        if kind == "image":
            records = self._open
        elif kind == "data":
            records = self._data
        else:
            raise ValueError(f"kind must be 'image' or 'data', got {kind!r}")
        before = records.size
        records.add_message(channel_id, log_time, publish_time, sequence, parts)
        size = records.size - before
        if kind == "image":
            if self.image_since is None:
                self.image_since = self.clock()
            self.image_bytes += size
            if count_as:
                self.image_counts[count_as] += 1
            if self.image_bytes >= self.chunk_bytes:
                self.close_image_chunk()
                if self.data_with_images:
                    self.write_data()
        else:
            if self.pending_since is None:
                self.pending_since = self.clock()
            self.pending_bytes += size
            if count_as:
                self.pending_counts[count_as] += 1
            if self.pending_bytes >= self.chunk_bytes:
                self.write_data()

    def age(self) -> float:
        """Seconds since the oldest message not yet written (0 when everything is written)."""
        oldest = min((t for t in (self.image_since, self.pending_since) if t is not None), default=None)
        return 0.0 if oldest is None else self.clock() - oldest

    def flush_due(self) -> bool:
        """Write everything if the oldest unwritten message is ``flush_interval_s`` old; True if it did."""
        if self.flush_interval_s is None or self.age() < self.flush_interval_s:
            return False
        self.close_image_chunk()
        self.write_data()
        return True

    def close_image_chunk(self) -> None:
        if self.image_since is None:
            return
        self._write_chunk(self._open)
        self._open.reset()
        self.durable_counts.update(self.image_counts)
        self.image_counts.clear()
        self.image_since = None
        self.image_bytes = 0

    def write_data(self) -> None:
        """Write the pending data messages as one chunk (after closing the open image chunk)."""
        if not self._data.num_messages:
            return
        self.close_image_chunk()             # one open chunk, as in mcap: never mix the kinds
        records_first = self._open if self._open.size else None   # registered since: they lead the chunk
        self._write_chunk(self._data, records_first)
        if records_first is not None:
            self._open.reset()
        self._data.reset()
        self.durable_counts.update(self.pending_counts)
        self.pending_counts.clear()
        self.pending_since = None
        self.pending_bytes = 0

    def _add_record(self, record: McapRecord) -> None:
        """A schema or channel record, registered: into the open chunk, where mcap's writer puts it."""
        builder = RecordBuilder()
        record.write(builder)
        self._open.append(builder.end())

    def _write_chunk(self, records: _ChunkRecords, records_first: _ChunkRecords | None = None) -> None:
        """Write the messages of ``records`` (after the schema and channel records of ``records_first``) as
        one chunk, then its message indexes, as mcap's ``Writer`` does; flush the stream to the kernel."""
        pieces: list[memoryview | bytes] = ([records.view()] if records_first is None
                                            else [records_first.view(), records.view()])
        shift = 0 if records_first is None else records_first.size
        uncompressed_size = sum(memoryview(piece).nbytes for piece in pieces)
        crc = 0
        for piece in pieces:
            crc = zlib.crc32(piece, crc)
        if self.compression:
            pieces = [_compress(self.compression, b"".join(pieces))]
        data_size = sum(len(piece) for piece in pieces)
        compression = self.compression.encode()
        stream = self.stream
        chunk_start = stream.tell()
        head = (_CHUNK_HEAD.pack(Opcode.CHUNK, _CHUNK_FIELDS + len(compression) + data_size, records.start_time,
                                 records.end_time, uncompressed_size, crc)
                + struct.pack("<I", len(compression)) + compression + struct.pack("<Q", data_size))
        stream.write(head)
        for piece in pieces:
            stream.write(piece)
        index_start = chunk_start + len(head) + data_size
        builder = RecordBuilder()
        offsets = {}
        for channel_id, entries in records.indexes.items():
            offsets[channel_id] = index_start + builder.count
            MessageIndex(channel_id, [(log_time, shift + offset) for log_time, offset in entries]).write(builder)
        indexes = builder.end()
        stream.write(indexes)
        stream.flush()
        self.writer.add_chunk(ChunkIndex(
            message_start_time=records.start_time, message_end_time=records.end_time,
            chunk_start_offset=chunk_start, chunk_length=len(head) + data_size, message_index_offsets=offsets,
            message_index_length=len(indexes), compression=self.compression, compressed_size=data_size,
            uncompressed_size=uncompressed_size), records)
        self.chunks_written += 1

    def flush(self) -> None:
        """Write the image chunk and the pending data, and flush the stream to the kernel."""
        self.close_image_chunk()
        self.write_data()
        self.writer.flush()                  # records outside chunks (header, metadata) too

    def finish(self) -> None:
        self.flush()
        self.writer.finish()
        self.stream.flush()


def _compress(compression: str, data: bytes) -> bytes:
    """``data`` compressed by the call mcap's writer makes for ``compression``."""
    if compression == "lz4":
        import lz4.frame
        return lz4.frame.compress(data)
    import zstandard
    return zstandard.compress(data)
