"""MCAP records of livedic recordings, on the ``mcap`` library, read within bounds (the read side of the container).

Reading. Records are parsed by mcap's own record classes (``mcap.records``) and
chunks broken up by ``mcap.stream_reader.breakup_chunk`` (which checks their CRC).
What the library's readers lack for files that may be cut short or damaged is
this thin layer:

* ``RecordScan`` frames the records of a byte range (opcode, length) and stops
  cleanly where the data stops: at a record that runs past the end of the file
  (where the writer died), at zero bytes (blocks never written before a crash),
  at the end of the file, or at the DataEnd/Footer record. It says which
  (``ScanEnd``) and how many bytes were whole (``valid_bytes``). mcap's
  ``StreamReader`` reads each field with whatever length the file claims (a
  flipped bit can make one read as large as the file) and cannot tell where a
  record starts; here no record over ``MAX_RECORD_BYTES`` is read and
  ``read_record`` hands mcap's parser the record's body only, so no field can
  reach past its record.
* ``open_chunk`` decompresses a chunk with its claimed size capped at
  ``MAX_CHUNK_BYTES`` before mcap breaks it up: the decompressors would allocate
  whatever size a corrupt or hostile chunk claims.
* ``read_summary`` checks the footer, the summary's CRC and the offsets of its
  chunk and metadata indexes (mcap's ``SeekingReader`` uses them unchecked) and
  returns an ``mcap.summary.Summary``, or why there is none.

Anything that does not parse raises ``Damaged`` (the message says what, without
the file name: the reader adds that).

Writing is ``acquire.recording.chunked_writer``'s.
"""

from __future__ import annotations

import dataclasses
import enum
import io
import struct
import zlib
from collections.abc import Iterator
from typing import Any, BinaryIO, cast

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, McapRecord, Message, Metadata,
                          MetadataIndex, Schema, Statistics)
from mcap.stream_reader import CRCValidationError, breakup_chunk
from mcap.summary import Summary

__all__ = ["Damaged", "MAGIC", "MAX_CHUNK_BYTES", "MAX_RECORD_BYTES", "MESSAGE_HEADER_BYTES", "RecordScan", "ScanEnd",
           "open_chunk", "parse_record", "read_record", "read_record_at", "read_summary"]

MAGIC = b"\x89MCAP0\r\n"
MAX_RECORD_BYTES = 1 << 30          # a record (chunk) claiming more is corrupt
MAX_CHUNK_BYTES = 1 << 30           # a chunk claiming more once decompressed is corrupt
MAX_METADATA_BYTES = 1 << 26
_HEAD = struct.Struct("<BQ")        # opcode, length: the 9 bytes before every record body
_FOOTER_BYTES = _HEAD.size + 20
# Any: each record class has a static read(stream), which mcap's base class McapRecord does not declare.
_RECORD_TYPES: dict[int, Any] = {
    Opcode.HEADER: Header, Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.MESSAGE: Message,
    Opcode.CHUNK: Chunk, Opcode.METADATA: Metadata, Opcode.CHUNK_INDEX: ChunkIndex,
    Opcode.METADATA_INDEX: MetadataIndex, Opcode.DATA_END: DataEnd, Opcode.FOOTER: Footer,
    Opcode.STATISTICS: Statistics}
MESSAGE_HEADER_BYTES = 2 + 4 + 8 + 8    # a Message record's fields before its data
# What mcap's record parsers raise on bytes that are not what they claim (struct.error: a short field;
# OverflowError: a length beyond any buffer, inside a chunk).
_PARSE_ERRORS = (McapError, ValueError, struct.error, OverflowError)


class Damaged(Exception):
    """A record that does not parse; the message says what is wrong."""


# ----------------------------------------------------------------------------- records

class _Body:
    """The next ``length`` bytes of ``f``, one record's body, for mcap's parsers.

    A field that would run past the body raises ``Damaged`` before anything is read;
    fields are read straight from ``f`` (a chunk's data is read once, into its own bytes).
    """

    def __init__(self, f: BinaryIO, length: int) -> None:
        self.f, self.left = f, length

    def read(self, size: int | None = -1) -> bytes:
        if size is None or not 0 <= size <= self.left:
            raise Damaged("a field runs past the end of its record")
        data = self.f.read(size)
        if len(data) < size:
            raise Damaged("the file ends inside the record")
        self.left -= size
        return data


def read_record(f: BinaryIO, opcode: int, length: int) -> McapRecord:
    """The ``mcap.records`` record of ``opcode`` whose ``length``-byte body starts at ``f``'s position."""
    record_type = _RECORD_TYPES[opcode]
    stream = ReadDataStream(_Body(f, length))  # type: ignore[arg-type]  # reads like the IO[bytes] it expects
    try:
        if record_type is Message:
            if length < MESSAGE_HEADER_BYTES:
                raise Damaged("a message record is shorter than its header")
            return Message.read(stream, length)
        return record_type.read(stream)
    except _PARSE_ERRORS as error:
        raise Damaged(f"bad {record_type.__name__.lower()} record ({type(error).__name__})") from None


def parse_record(opcode: int, body: bytes) -> McapRecord:
    """The ``mcap.records`` record of ``opcode`` parsed from ``body`` (bytes), or ``Damaged``."""
    return read_record(io.BytesIO(body), opcode, len(body))


class ScanEnd(enum.Enum):
    """Why a ``RecordScan`` stopped."""
    DATA_END = "data end"            # the DataEnd (or Footer) record: the data section is complete
    END_OF_RANGE = "end of range"    # the last record ended exactly at the end (a section, or a file cut there)
    PARTIAL = "partial record"       # a record runs past the end: the writer stopped inside it
    ZEROS = "zeros"                  # zero bytes where a record starts: blocks never written before a crash
    TOO_LARGE = "too large"          # a record claims more than MAX_RECORD_BYTES: corrupt

    @property
    def complete(self) -> bool:
        """The data section ended as a finished file's does."""
        return self is ScanEnd.DATA_END


class RecordScan:
    """The records of ``f`` from byte ``start`` to ``end``, in order, framed within bounds.

    Iterating yields ``(offset, opcode, length)`` of each whole record with ``f`` at the
    start of its body, which the caller may read with ``read_record(f, opcode, length)``
    (or leave: the scan goes on from the record's end). Afterwards ``stop`` says why the
    scan ended (``ScanEnd``), ``valid_bytes`` where the last whole record ends and
    ``claimed`` what a ``TOO_LARGE`` record claimed.
    """

    def __init__(self, f: BinaryIO, start: int, end: int) -> None:
        self.f, self.start, self.end = f, start, end
        self.valid_bytes = start
        self.stop: ScanEnd | None = None
        self.claimed = 0

    def __iter__(self) -> Iterator[tuple[int, int, int]]:
        f, pos, end = self.f, self.start, self.end
        while True:
            self.valid_bytes = pos
            if pos >= end:
                self.stop = ScanEnd.END_OF_RANGE
                return
            f.seek(pos)
            head = f.read(_HEAD.size)
            if len(head) < _HEAD.size:
                self.stop = ScanEnd.PARTIAL
                return
            opcode, length = _HEAD.unpack(head)
            if opcode == 0:
                self.stop = ScanEnd.ZEROS
                return
            if length > end - pos - _HEAD.size:
                self.stop = ScanEnd.PARTIAL
                return
            if length > MAX_RECORD_BYTES:
                self.stop, self.claimed = ScanEnd.TOO_LARGE, length
                return
            if opcode in (Opcode.DATA_END, Opcode.FOOTER):
                self.stop = ScanEnd.DATA_END
                return
            yield pos, opcode, length
            pos += _HEAD.size + length


def read_record_at(f: BinaryIO, offset: int, length: int, opcode: int) -> McapRecord:
    """The record of ``opcode`` that an index says is ``length`` bytes at ``offset`` (``Damaged`` if not)."""
    f.seek(offset)
    head = f.read(_HEAD.size)
    if len(head) < _HEAD.size or _HEAD.unpack(head) != (opcode, length - _HEAD.size):
        raise Damaged(f"no {Opcode(opcode).name.lower()} record where the index points")
    return read_record(f, opcode, length - _HEAD.size)


# ----------------------------------------------------------------------------- chunks

def _decompress(chunk):
    """The chunk's records, uncompressed, never more than it claims (itself capped at MAX_CHUNK_BYTES)."""
    size = chunk.uncompressed_size
    if size > MAX_CHUNK_BYTES:
        raise Damaged(f"chunk claims {size} uncompressed bytes")
    compression = chunk.compression
    if compression == "":
        return chunk.data
    try:
        if compression == "lz4":
            import lz4.frame
            decompressor = lz4.frame.LZ4FrameDecompressor()
            data = decompressor.decompress(chunk.data, max_length=size)
            if not decompressor.eof:
                raise Damaged(f"lz4 chunk holds more than its header's {size} bytes, or is cut short")
            return data
        if compression == "zstd":
            import zstandard
            if zstandard.frame_content_size(chunk.data) > size:      # it would allocate what the frame claims
                raise Damaged(f"zstd frame claims more than the chunk's {size} bytes")
            return zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=size)
    except Damaged:
        raise
    except Exception as error:  # noqa: BLE001 - decompressors raise assorted types on garbage
        raise Damaged(f"{compression} decompression failed ({type(error).__name__})") from None
    raise Damaged(f"unsupported chunk compression {compression!r}")


def open_chunk(chunk: Chunk) -> list[McapRecord]:
    """The records of ``chunk`` (an ``mcap.records.Chunk``): Schema, Channel and Message, in order.

    Decompressed within bounds, CRC checked (when the writer stored one) and broken up
    by mcap; raises ``Damaged`` when any of it fails.
    """
    data = _decompress(chunk)
    if len(data) != chunk.uncompressed_size:
        raise Damaged(f"chunk holds {len(data)} bytes, its header says {chunk.uncompressed_size}")
    try:
        return breakup_chunk(dataclasses.replace(chunk, compression="", data=data), validate_crc=True)
    except CRCValidationError:
        raise Damaged("chunk CRC mismatch") from None
    except _PARSE_ERRORS as error:
        raise Damaged(f"bad record inside the chunk ({type(error).__name__})") from None


# ----------------------------------------------------------------------------- summary

def read_summary(f: BinaryIO, size: int, data_start: int) -> tuple[Summary | None, str]:
    """``(summary, problem)``: the file's ``mcap.summary.Summary`` when it has a sound one, else None.

    ``problem`` is "" when there is simply no summary (a file cut short, or written
    without one) and otherwise says, for people, what is wrong with it ("its summary
    fails its CRC" ...): the reader then reads the file record by record.
    """
    if size < data_start + _FOOTER_BYTES + len(MAGIC):
        return None, ""
    f.seek(size - len(MAGIC))
    if f.read(len(MAGIC)) != MAGIC:
        return None, "it does not end with an MCAP footer (no index)"
    footer_start = size - len(MAGIC) - _FOOTER_BYTES
    f.seek(footer_start)
    head = f.read(_FOOTER_BYTES)
    if _HEAD.unpack_from(head) != (Opcode.FOOTER, 20):
        return None, "its footer is damaged"
    footer = cast(Footer, parse_record(Opcode.FOOTER, head[_HEAD.size:]))
    if footer.summary_start == 0:
        return None, ""                                  # a complete file written without a summary
    if not data_start <= footer.summary_start <= footer_start:
        return None, "its footer points outside the file"
    if footer_start - footer.summary_start > MAX_RECORD_BYTES:
        return None, f"its summary claims {footer_start - footer.summary_start} bytes"
    f.seek(footer.summary_start)
    data = f.read(footer_start - footer.summary_start)
    # The summary CRC covers the summary and the footer up to its own CRC field.
    if footer.summary_crc and zlib.crc32(head[:-4], zlib.crc32(data)) != footer.summary_crc:
        return None, "its summary fails its CRC"
    try:
        return _parse_summary(data, data_start, footer.summary_start), ""
    except Damaged as bad:
        return None, f"its summary is damaged ({bad})"


def _parse_summary(data, data_start, data_end):
    """An ``mcap.summary.Summary`` from the summary section's bytes; indexes must point into the data section."""
    summary = Summary()
    wanted = (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.CHUNK_INDEX, Opcode.METADATA_INDEX, Opcode.STATISTICS)
    f = io.BytesIO(data)
    scan = RecordScan(f, 0, len(data))
    for _, opcode, length in scan:
        if opcode not in wanted:
            continue
        record = read_record(f, opcode, length)
        if opcode == Opcode.SCHEMA:
            summary.schemas[record.id] = record
        elif opcode == Opcode.CHANNEL:
            summary.channels[record.id] = record
        elif opcode == Opcode.STATISTICS:
            summary.statistics = record          # the message counts per channel, without reading the data
        elif opcode == Opcode.CHUNK_INDEX:
            if not (data_start <= record.chunk_start_offset
                    and record.chunk_start_offset + record.chunk_length <= data_end
                    and _HEAD.size <= record.chunk_length <= MAX_RECORD_BYTES):
                raise Damaged("a chunk index points outside the data section")
            summary.chunk_indexes.append(record)
        else:
            if not (data_start <= record.offset and record.offset + record.length <= data_end
                    and _HEAD.size <= record.length <= MAX_METADATA_BYTES):
                raise Damaged("a metadata index points outside the data section")
            summary.metadata_indexes.append(record)
    if scan.stop is not ScanEnd.END_OF_RANGE:
        raise Damaged("a summary record runs past the summary")
    for channel in summary.channels.values():
        if channel.schema_id and channel.schema_id not in summary.schemas:
            raise Damaged(f"channel {channel.topic!r} has no schema")
    summary.chunk_indexes.sort(key=lambda chunk: chunk.chunk_start_offset)
    return summary
