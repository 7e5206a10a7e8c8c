"""Read livedic recordings (MCAP): replay frames, read results, events and metadata, recover crashes.

Every reader takes the fastest safe path:

* **Indexed.** The file ends with the MCAP magic, its footer parses, and the summary
  (schemas, channels, chunk and metadata indexes) passes its CRC and bounds checks:
  only the chunks holding the wanted topics are read (``read_results`` never touches
  an image chunk; the recorder keeps image and data chunks apart).
* **Recovery scan.** Otherwise (the recorder was killed, the disk filled up, the
  summary is damaged) records are read one by one from the start, as the
  non-seeking MCAP reader does, until the data ends: at a partial record (where
  the writer died), at zero bytes, at the end of the file or at the DataEnd record.
  A truncated file is not an error: the reader logs one note (logger
  ``acquire.mcap_replay``) saying so and how many messages it recovered, and
  ``inspect_recording`` reports the same.

Bad input raises ``RecordingError`` (a ``ValueError``; ``McapSource`` raises
``RecordingSourceError``, which is also an ``acquire.base.SourceError``) with one
line naming the file and the problem: missing file, empty file, not MCAP, truncated
inside the header, not written by livedic, corrupt record. Records are parsed here
with explicit bounds checks (no read is sized by an unchecked length, so garbage
cannot allocate gigabytes or hang); chunk CRCs are verified. Payloads are protobuf
or JSON only: nothing from a file is ever unpickled or evaluated.

Examples
--------
>>> from acquire.mcap_replay import McapSource, read_results   # doctest: +SKIP
>>> with McapSource("session.mcap", realtime=False) as source:  # doctest: +SKIP
...     for frame in source:
...         print(frame.index, frame.image.shape)
>>> results = read_results("session.mcap")                       # doctest: +SKIP
>>> results[0].u, results[0].ok                                   # doctest: +SKIP
"""

import json
import logging
import os
import struct
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np

from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.stream import recording_schema as rs

__all__ = ["McapSource", "RecordedEvent", "RecordedResults", "RecordingError", "RecordingInfo",
           "RecordingSourceError", "inspect_recording", "iter_results", "read_events", "read_results",
           "read_session", "recover"]

log = logging.getLogger(__name__)

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
OP_CHUNK_INDEX, OP_METADATA, OP_METADATA_INDEX, OP_DATA_END = 0x08, 0x0C, 0x0D, 0x0F
_FOOTER_RECORD = 1 + 8 + 20
MAX_RECORD_BYTES = 1 << 30          # a record (chunk) larger than this is treated as corrupt


class RecordingError(ValueError):
    """A recording that cannot be read as asked; the message is one line naming the file."""


class RecordingSourceError(SourceError, RecordingError):
    """``RecordingError`` raised by ``McapSource``: also a ``SourceError`` for the live pipeline."""


@dataclass(frozen=True)
class RecordedResults:
    """One frame's results as recorded on ``/dic/results``.

    Arrays have shape (N,): ``point_id`` uint32, ``ok`` bool, ``status``/``iterations``
    int32/uint32, the rest float64. ``ux, uy, vx, vy, status, iterations`` are None
    when they were not recorded. They may be read-only views into the file data.
    """
    frame_index: int
    timestamp_ns: int
    point_id: np.ndarray
    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    v: np.ndarray
    zncc: np.ndarray
    ok: np.ndarray
    ux: np.ndarray = None
    uy: np.ndarray = None
    vx: np.ndarray = None
    vy: np.ndarray = None
    status: np.ndarray = None
    iterations: np.ndarray = None
    method: str = ""
    processing_ns: int = 0
    latency_ns: int = 0
    reference_frame_index: int = 0
    dropped_frames: int = 0
    publish_time_ns: int = 0            # host clock when the recorder wrote it


@dataclass(frozen=True)
class RecordedEvent:
    """A note from ``/livedic/events``."""
    timestamp_ns: int
    kind: str
    message: str
    level: str


@dataclass
class RecordingInfo:
    """What a reader found in a recording (see ``inspect_recording``)."""
    path: str
    size_bytes: int
    indexed: bool = False             # read through a valid summary/index
    truncated: bool = False           # data ends early: no DataEnd/footer (crash, kill, disk full)
    library: str = ""
    is_livedic: bool = False
    message_counts: dict = field(default_factory=dict)   # topic -> messages read
    valid_bytes: int = 0              # bytes of complete records (recovery scan)
    corrupt_chunks: int = 0           # skipped by ``recover``
    start_ns: int = None
    end_ns: int = None
    note: str = ""                    # one line for people, "" when all is normal

    @property
    def frames(self):
        return self.message_counts.get(rs.TOPIC_IMAGE, 0)


# ----------------------------------------------------------------------------- low-level records

class _Bad(Exception):
    """A record that does not parse; the message says what is wrong."""


class _Cursor:
    """Bounds-checked reader over ``buf[pos:end]``."""
    __slots__ = ("buf", "pos", "end")

    def __init__(self, buf, pos=0, end=None):
        self.buf, self.pos, self.end = buf, pos, len(buf) if end is None else end

    def take(self, n):
        if n > self.end - self.pos:
            raise _Bad(f"a field of {n} bytes runs past the end of its record")
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def _unpack(self, fmt, size):
        if size > self.end - self.pos:
            raise _Bad("record is shorter than its fields")
        (value,) = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return value

    def u16(self):
        return self._unpack("<H", 2)

    def u32(self):
        return self._unpack("<I", 4)

    def u64(self):
        return self._unpack("<Q", 8)

    def string(self):
        try:
            return bytes(self.take(self.u32())).decode("utf-8")
        except UnicodeDecodeError:
            raise _Bad("a string is not UTF-8") from None

    def string_map(self):
        n = self.u32_checked()
        sub = _Cursor(self.buf, self.pos, self.pos + n)
        self.pos = sub.end
        out = {}
        while sub.pos < sub.end:
            key = sub.string()
            out[key] = sub.string()
        return out

    def u32_checked(self):
        n = self.u32()
        if n > self.end - self.pos:
            raise _Bad(f"a field of {n} bytes runs past the end of its record")
        return n

    def rest(self):
        return self.take(self.end - self.pos)


@dataclass(frozen=True)
class _Schema:
    id: int
    name: str
    encoding: str
    data: bytes


@dataclass(frozen=True)
class _Channel:
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict


@dataclass(frozen=True)
class _Message:
    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: memoryview


def _parse_schema(c):
    schema_id = c.u16()
    if schema_id == 0:
        raise _Bad("schema id 0")
    name, encoding = c.string(), c.string()
    return _Schema(schema_id, name, encoding, bytes(c.take(c.u32())))


def _parse_channel(c):
    channel_id, schema_id = c.u16(), c.u16()
    topic, encoding = c.string(), c.string()
    return _Channel(channel_id, schema_id, topic, encoding, c.string_map())


def _parse_message(c):
    channel_id, sequence, log_time, publish_time = c.u16(), c.u32(), c.u64(), c.u64()
    return _Message(channel_id, sequence, log_time, publish_time, c.rest())


def _parse_chunk(c):
    start, end, usize, crc = c.u64(), c.u64(), c.u64(), c.u32()
    compression = c.string()
    n = c.u64()
    if n > c.end - c.pos:
        raise _Bad("chunk data runs past the end of its record")
    return compression, c.take(n), usize, crc


def _decompress(compression, data, usize, crc):
    if usize > MAX_RECORD_BYTES:
        raise _Bad(f"chunk claims {usize} uncompressed bytes")
    try:
        if compression == "":
            out = data
        elif compression == "lz4":
            import lz4.frame
            out = lz4.frame.decompress(bytes(data))
        elif compression == "zstd":
            import zstandard
            out = zstandard.ZstdDecompressor().decompress(bytes(data), max_output_size=usize)
        else:
            raise _Bad(f"unsupported chunk compression {compression!r}")
    except _Bad:
        raise
    except Exception as error:  # noqa: BLE001 - decompressors raise assorted types on garbage
        raise _Bad(f"{compression} decompression failed ({type(error).__name__})") from None
    if len(out) != usize:
        raise _Bad(f"chunk holds {len(out)} bytes, its header says {usize}")
    if crc and zlib.crc32(out) != crc:
        raise _Bad("chunk CRC mismatch")
    return memoryview(out)


def _chunk_records(body):
    """Schemas, channels and messages of a chunk record body, all parsed before any is used."""
    compression, data, usize, crc = _parse_chunk(_Cursor(body))
    buf = _decompress(compression, data, usize, crc)
    out, pos, n = [], 0, len(buf)
    while pos < n:
        if n - pos < 9:
            raise _Bad("chunk ends inside a record header")
        opcode = buf[pos]
        (length,) = struct.unpack_from("<Q", buf, pos + 1)
        if length > n - pos - 9:
            raise _Bad("a record runs past the end of its chunk")
        c = _Cursor(buf, pos + 9, pos + 9 + length)
        if opcode == OP_MESSAGE:
            out.append(_parse_message(c))
        elif opcode == OP_CHANNEL:
            out.append(_parse_channel(c))
        elif opcode == OP_SCHEMA:
            out.append(_parse_schema(c))
        pos += 9 + length
    return out


@dataclass
class _ChunkIndex:
    offset: int
    length: int
    channel_ids: frozenset


@dataclass
class _Summary:
    schemas: dict
    channels: dict
    chunks: list
    metadata: list              # (offset, length, name)


# ----------------------------------------------------------------------------- the file reader

class _Recording:
    """A validated MCAP file: header checked, summary loaded when there is a valid one."""

    def __init__(self, path, error=RecordingError):
        self.path = os.fspath(path)
        self.name = self.path
        self.error = error
        try:
            with open(self.path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                self._check_start(f, size)
                self.summary, self.summary_note = self._read_summary(f, size)
        except FileNotFoundError:
            raise error(f"{self.name} does not exist") from None
        except IsADirectoryError:
            raise error(f"{self.name} is a directory, not an MCAP recording") from None
        except OSError as oserror:
            raise error(f"{self.name} cannot be read ({oserror.strerror or oserror})") from None
        self.info = RecordingInfo(self.path, size, indexed=self.summary is not None, library=self.library,
                                  valid_bytes=size if self.summary is not None else self.data_start)
        self.schemas = dict(self.summary.schemas) if self.summary else {}
        self.channels = dict(self.summary.channels) if self.summary else {}
        self.metadata_names = {name for _, _, name in self.summary.metadata} if self.summary else set()
        if self.summary is None:
            self._probe()
        self.info.is_livedic = self._is_livedic()

    # -- opening checks

    def _check_start(self, f, size):
        head = f.read(8)
        if size == 0:
            raise self.error(f"{self.name} is empty (0 bytes), not an MCAP recording")
        if head != MAGIC:
            if len(head) < 8 and MAGIC.startswith(head):
                raise self.error(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
            raise self.error(f"{self.name} is not an MCAP file (bad magic bytes {head[:8]!r})")
        record = f.read(9)
        if len(record) < 9:
            raise self.error(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
        opcode, length = record[0], struct.unpack_from("<Q", record, 1)[0]
        if opcode != OP_HEADER:
            raise self.error(f"{self.name} is not a valid MCAP file (first record has opcode {opcode:#04x}, "
                             f"not a header)")
        if length > size - 17:
            raise self.error(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
        if length > 1 << 20:
            raise self.error(f"{self.name} is corrupt: its header record claims {length} bytes")
        try:
            c = _Cursor(f.read(length))
            self.profile, self.library = c.string(), c.string()
        except _Bad as bad:
            raise self.error(f"{self.name} is corrupt: bad header record ({bad})") from None
        self.data_start = 17 + length

    def _read_summary(self, f, size):
        """(summary or None, note); a damaged summary is a note, not an error."""
        if size < self.data_start + _FOOTER_RECORD + 8:
            return None, ""
        f.seek(size - 8)
        if f.read(8) != MAGIC:
            return None, "it does not end with an MCAP footer (no index)"
        f.seek(size - 8 - _FOOTER_RECORD)
        footer = f.read(_FOOTER_RECORD)
        if footer[0] != OP_FOOTER or struct.unpack_from("<Q", footer, 1)[0] != 20:
            return None, "its footer is damaged"
        summary_start, summary_offset_start, crc = struct.unpack_from("<QQI", footer, 9)
        summary_end = size - 8 - _FOOTER_RECORD
        if summary_start == 0:
            return None, ""                               # complete file written without a summary
        if not self.data_start <= summary_start <= summary_end:
            return None, "its footer points outside the file"
        if summary_end - summary_start > MAX_RECORD_BYTES:
            return None, f"its summary claims {summary_end - summary_start} bytes"
        f.seek(summary_start)
        data = f.read(summary_end - summary_start)
        if crc and zlib.crc32(footer[:25], zlib.crc32(data)) != crc:
            return None, "its summary fails its CRC"
        try:
            summary = self._parse_summary(memoryview(data), summary_start)
        except _Bad as bad:
            return None, f"its summary is damaged ({bad})"
        return summary, ""

    def _parse_summary(self, buf, base):
        schemas, channels, chunks, metadata = {}, {}, [], []
        pos, n = 0, len(buf)
        while pos < n:
            if n - pos < 9:
                raise _Bad("summary ends inside a record")
            opcode = buf[pos]
            (length,) = struct.unpack_from("<Q", buf, pos + 1)
            if length > n - pos - 9:
                raise _Bad("a summary record runs past the summary")
            c = _Cursor(buf, pos + 9, pos + 9 + length)
            if opcode == OP_SCHEMA:
                schema = _parse_schema(c)
                schemas[schema.id] = schema
            elif opcode == OP_CHANNEL:
                channel = _parse_channel(c)
                channels[channel.id] = channel
            elif opcode == OP_CHUNK_INDEX:
                c.u64(), c.u64()
                offset, length_ = c.u64(), c.u64()
                ids = set()
                n_offsets = c.u32_checked()
                sub = _Cursor(buf, c.pos, c.pos + n_offsets)
                c.pos = sub.end
                while sub.pos < sub.end:
                    ids.add(sub.u16())
                    sub.u64()
                if not self.data_start <= offset or offset + length_ > base or not 9 <= length_ <= MAX_RECORD_BYTES:
                    raise _Bad("a chunk index points outside the data section")
                chunks.append(_ChunkIndex(offset, length_, frozenset(ids)))
            elif opcode == OP_METADATA_INDEX:
                offset, length_, name = c.u64(), c.u64(), c.string()
                if not self.data_start <= offset or offset + length_ > base or not 9 <= length_ <= 1 << 26:
                    raise _Bad("a metadata index points outside the data section")
                metadata.append((offset, length_, name))
            pos += 9 + length
        for channel in channels.values():
            if channel.schema_id and channel.schema_id not in schemas:
                raise _Bad(f"channel {channel.topic!r} has no schema")
        chunks.sort(key=lambda chunk: chunk.offset)
        return _Summary(schemas, channels, chunks, metadata)

    def _probe(self):
        """Recovery-scan the start of the file (up to the first chunk) for channels and metadata."""
        self.probe_metadata = {}
        self.probe_session = None
        try:
            scratch = RecordingInfo(self.path, self.info.size_bytes)
            for kind, item in self._linear(strict=False, stop_after_first_chunk=True, info=scratch):
                if kind == "metadata":
                    self.metadata_names.add(item[0])
                    self.probe_metadata.setdefault(item[0], item[1])
                elif kind == "message" and self.probe_session is None:
                    if self.channels[item.channel_id].topic == rs.TOPIC_SESSION:
                        self.probe_session = item
        except RecordingError:
            pass

    def _is_livedic(self):
        if self.library.startswith("livedic") or rs.METADATA_NAME in self.metadata_names:
            return True
        return self.image_channel_ids() != set()

    def require_livedic(self):
        if not self.info.is_livedic:
            raise self.error(f"{self.name} was not written by livedic (no {rs.TOPIC_IMAGE} RawImage channel)")

    def channel_ids(self, topic, schema_name=None):
        out = set()
        for channel in self.channels.values():
            if channel.topic != topic or channel.message_encoding != "protobuf":
                continue
            schema = self.schemas.get(channel.schema_id)
            if schema_name is None or (schema is not None and schema.name == schema_name):
                out.add(channel.id)
        return out

    def image_channel_ids(self):
        return self.channel_ids(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA)

    # -- scanning

    def _open_file(self):
        try:
            return open(self.path, "rb")
        except OSError as error:
            raise self.error(f"{self.name} cannot be read any more ({error.strerror or error})") from None

    def _corrupt(self, what, offset, bad):
        return self.error(f"{self.name} is corrupt: {what} at byte {offset} ({bad}); "
                          f"`recover` can rewrite what is readable")

    def _linear(self, *, strict=True, stop_after_first_chunk=False, info=None):
        """Recovery scan from the start: yields ("schema"|"channel"|"message"|"metadata", item).

        Updates ``self.info``: ``valid_bytes``, ``truncated``, ``corrupt_chunks``. With
        ``strict`` a corrupt record raises; otherwise a corrupt record whose length is
        intact is skipped (and counted) and the scan goes on.
        """
        info = self.info if info is None else info
        with self._open_file() as f:
            size = os.fstat(f.fileno()).st_size
            pos = self.data_start
            f.seek(pos)
            info.truncated = True
            info.valid_bytes = pos
            while True:
                if pos == size:
                    break
                head = f.read(9)
                if len(head) < 9:
                    break                                     # partial record header: the writer died here
                opcode = head[0]
                (length,) = struct.unpack_from("<Q", head, 1)
                if opcode == 0:
                    break                                     # zeros: unwritten blocks after a crash
                if length > size - pos - 9:
                    break                                     # partial record
                if length > MAX_RECORD_BYTES:
                    if strict:
                        raise self._corrupt("a record", pos, f"it claims {length} bytes")
                    break
                if opcode in (OP_DATA_END, OP_FOOTER):
                    info.truncated = False
                    info.valid_bytes = pos
                    break
                wanted = opcode in (OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_METADATA, OP_HEADER)
                if not wanted:
                    f.seek(length, os.SEEK_CUR)
                    pos += 9 + length
                    info.valid_bytes = pos
                    continue
                body = memoryview(f.read(length))
                if len(body) < length:
                    break
                try:
                    if opcode == OP_CHUNK:
                        items = _chunk_records(body)
                    elif opcode == OP_SCHEMA:
                        items = [_parse_schema(_Cursor(body))]
                    elif opcode == OP_CHANNEL:
                        items = [_parse_channel(_Cursor(body))]
                    elif opcode == OP_MESSAGE:
                        items = [_parse_message(_Cursor(body))]
                    elif opcode == OP_METADATA:
                        c = _Cursor(body)
                        items = [(c.string(), c.string_map())]
                    else:
                        raise _Bad("a second header record")
                except _Bad as bad:
                    what = "a chunk" if opcode == OP_CHUNK else f"a record (opcode {opcode:#04x})"
                    if strict:
                        raise self._corrupt(what, pos, bad) from None
                    info.corrupt_chunks += 1
                    items = []
                for item in items:
                    kind = self._register(item, strict, pos)
                    if kind:
                        yield kind, item
                pos += 9 + length
                info.valid_bytes = pos
                if opcode == OP_CHUNK and stop_after_first_chunk:
                    return
        if info.truncated and not stop_after_first_chunk:
            info.note = (f"{self.name} is truncated (the recording did not finish: crash, kill or disk full); "
                         f"read {sum(info.message_counts.values())} messages "
                         f"({info.frames} frames) from the first {info.valid_bytes} of {size} bytes")

    def _register(self, item, strict, pos):
        if isinstance(item, tuple):
            return "metadata"
        if isinstance(item, _Schema):
            self.schemas[item.id] = item
            return "schema"
        if isinstance(item, _Channel):
            if item.schema_id and item.schema_id not in self.schemas:
                if strict:
                    raise self._corrupt("a channel", pos, f"schema {item.schema_id} is unknown")
                return None
            self.channels[item.id] = item
            return "channel"
        if item.channel_id not in self.channels:
            if strict:
                raise self._corrupt("a message", pos, f"channel {item.channel_id} is unknown")
            return None
        return "message"

    def _indexed(self, channel_ids):
        """Messages of ``channel_ids`` (None: all) through the chunk index, in file order."""
        with self._open_file() as f:
            for chunk in self.summary.chunks:
                if channel_ids is not None and chunk.channel_ids and not chunk.channel_ids & channel_ids:
                    continue
                f.seek(chunk.offset)
                head = f.read(9)
                if len(head) < 9 or head[0] != OP_CHUNK or struct.unpack_from("<Q", head, 1)[0] != chunk.length - 9:
                    raise self._corrupt("the chunk index", chunk.offset, "no chunk where it points")
                body = memoryview(f.read(chunk.length - 9))
                try:
                    items = _chunk_records(body)
                except _Bad as bad:
                    raise self._corrupt("a chunk", chunk.offset, bad) from None
                for item in items:
                    if isinstance(item, _Message):
                        if item.channel_id not in self.channels:
                            raise self._corrupt("a message", chunk.offset, f"channel {item.channel_id} is unknown")
                        if channel_ids is None or item.channel_id in channel_ids:
                            yield item
                    elif isinstance(item, _Channel) and item.id not in self.channels:
                        self.channels[item.id] = item
                    elif isinstance(item, _Schema) and item.id not in self.schemas:
                        self.schemas[item.id] = item

    def messages(self, topics=None):
        """Yield ``_Message`` for ``topics`` (None: all), in file order, by the best path."""
        counts = Counter()
        self.info.message_counts = counts
        if self.summary is not None:
            ids = None if topics is None else {cid for cid, ch in self.channels.items() if ch.topic in topics}
            source = self._indexed(ids)
        else:
            source = (item for kind, item in self._linear() if kind == "message")
        for message in source:
            topic = self.channels[message.channel_id].topic
            counts[topic] += 1
            if topics is None or topic in topics:
                if self.info.start_ns is None or message.log_time < self.info.start_ns:
                    self.info.start_ns = message.log_time
                if self.info.end_ns is None or message.log_time > self.info.end_ns:
                    self.info.end_ns = message.log_time
                yield message
        if self.info.truncated and self.info.note:
            log.warning("note: %s", self.info.note)
        elif self.summary_note and not self.info.note:
            self.info.note = f"{self.name}: {self.summary_note}; it was read record by record instead"
            log.warning("note: %s", self.info.note)

    def session_strings(self):
        """The ``livedic.session`` string map (Metadata record, else the first session message)."""
        if self.summary is not None:
            with self._open_file() as f:
                for offset, length, name in self.summary.metadata:
                    if name != rs.METADATA_NAME:
                        continue
                    f.seek(offset)
                    record = memoryview(f.read(length))
                    try:
                        if len(record) < 9 or record[0] != OP_METADATA:
                            raise _Bad("no metadata record where the index points")
                        c = _Cursor(record, 9)
                        c.string()
                        return c.string_map()
                    except _Bad as bad:
                        raise self._corrupt("the session metadata", offset, bad) from None
            for message in self.messages({rs.TOPIC_SESSION}):
                return self._decode_session(message)
            return None
        if rs.METADATA_NAME in self.probe_metadata:
            return self.probe_metadata[rs.METADATA_NAME]
        if self.probe_session is not None:
            return self._decode_session(self.probe_session)
        return None

    def _decode_session(self, message):
        try:
            return dict(rs.Session.FromString(bytes(message.data)).metadata)
        except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
            raise self.error(f"{self.name} is corrupt: undecodable session message ({type(error).__name__})") \
                from None


# ----------------------------------------------------------------------------- public readers

def _open(path, error=RecordingError):
    recording = _Recording(path, error)
    recording.require_livedic()
    return recording


def read_session(path):
    """Session metadata of a recording, with non-string values decoded from JSON.

    Raises
    ------
    RecordingError
        Not a readable livedic recording, or it has no session metadata.
    """
    recording = _open(path)
    strings = recording.session_strings()
    if strings is None:
        raise RecordingError(f"{recording.name} has no session metadata ({rs.METADATA_NAME})")
    return rs.metadata_from_strings(strings)


def iter_results(path):
    """Yield ``RecordedResults`` per frame from ``/dic/results``, in recorded order."""
    recording = _open(path)
    ids = recording.channel_ids(rs.TOPIC_RESULTS, rs.FRAME_RESULTS_SCHEMA)
    for message in recording.messages({rs.TOPIC_RESULTS}):
        if message.channel_id not in ids and recording.summary is None:
            ids = recording.channel_ids(rs.TOPIC_RESULTS, rs.FRAME_RESULTS_SCHEMA)
        if message.channel_id not in ids:
            continue
        try:
            values = rs.decode_results(message.data)
        except rs.WireError as bad:
            raise RecordingError(f"{recording.name} is corrupt: results message at log time {message.log_time} "
                                 f"({bad})") from None
        yield RecordedResults(publish_time_ns=message.publish_time, **values)


def read_results(path):
    """List of ``RecordedResults``, one per recorded frame (see ``iter_results``)."""
    return list(iter_results(path))


def read_events(path):
    """List of ``RecordedEvent`` from ``/livedic/events``."""
    recording = _open(path)
    out = []
    for message in recording.messages({rs.TOPIC_EVENTS}):
        try:
            event = rs.Event.FromString(bytes(message.data))
        except Exception as error:  # noqa: BLE001
            raise RecordingError(f"{recording.name} is corrupt: undecodable event at log time "
                                 f"{message.log_time} ({type(error).__name__})") from None
        out.append(RecordedEvent(event.timestamp_ns, event.kind, event.message, event.level))
    return out


def inspect_recording(path):
    """``RecordingInfo`` for any MCAP file: how it reads, what it holds, whether it is truncated.

    Reads every message (the recovery scan, or the index); raises ``RecordingError``
    only when the file is not MCAP or is corrupt.
    """
    recording = _Recording(path)
    for _ in recording.messages():
        pass
    return recording.info


class McapSource(FrameSource):
    """Frames from a livedic recording's ``/camera/image`` channel.

    Parameters
    ----------
    path : str or os.PathLike
    realtime : bool
        Sleep so that frames come at the recorded pace (log time deltas); otherwise
        as fast as possible.

    Frames have the recorded index (MCAP sequence, or ``/camera/frame_info``),
    timestamp (the message log time), pixel format and metadata. Images are
    read-only views into the data read from the file (no copy); copy one before
    writing to it.

    Raises
    ------
    RecordingSourceError
        At construction, for a file that is not a livedic recording (one line); during
        iteration, at a corrupt record (frames before it have been delivered).
    """

    def __init__(self, path, *, realtime=False):
        self._recording = _open(path, RecordingSourceError)
        self.path = self._recording.path
        self.uri = f"mcap:{self.path}"
        self.realtime = bool(realtime)
        self._closed = False
        try:
            strings = self._recording.session_strings()
        except RecordingError:
            strings = None
        self.session = rs.metadata_from_strings(strings) if strings else {}

    @property
    def info(self):
        """``RecordingInfo`` of the last (or current) pass over the file."""
        return self._recording.info

    @property
    def settings(self):
        return {"kind": "mcap_replay", "path": self.path, "realtime": self.realtime,
                "recorded_source_uri": self.session.get("source_uri", ""),
                "recorded_start_time": self.session.get("start_time", "")}

    def close(self):
        self._closed = True

    def __iter__(self):
        recording = self._recording
        name = recording.name
        image_ids = recording.image_channel_ids()
        info_ids = recording.channel_ids(rs.TOPIC_FRAME_INFO, rs.FRAME_INFO_SCHEMA)
        pending_info = None
        first = None
        for message in recording.messages({rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO}):
            if self._closed:
                return
            if recording.summary is None and message.channel_id not in image_ids | info_ids:
                image_ids = recording.image_channel_ids()
                info_ids = recording.channel_ids(rs.TOPIC_FRAME_INFO, rs.FRAME_INFO_SCHEMA)
            if message.channel_id in info_ids:
                try:
                    pending_info = rs.FrameInfo.FromString(bytes(message.data))
                except Exception as error:  # noqa: BLE001
                    raise RecordingSourceError(f"{name} is corrupt: undecodable frame info at log time "
                                               f"{message.log_time} ({type(error).__name__})") from None
                continue
            if message.channel_id not in image_ids:
                continue
            try:
                image, encoding, _, _ = rs.decode_raw_image(message.data)
            except rs.WireError as bad:
                raise RecordingSourceError(f"{name} is corrupt: image message at log time {message.log_time} "
                                           f"({bad})") from None
            frame = self._frame(message, image, encoding, pending_info)
            pending_info = None
            if self.realtime:
                first = self._pace(first, frame.timestamp_ns)
            if self._closed:
                return
            yield frame

    @staticmethod
    def _frame(message, image, encoding, info):
        index = message.sequence
        pixel_format = "Mono8" if image.dtype == np.uint8 else "Mono16"
        metadata = {}
        if info is not None and (info.frame_index & 0xFFFFFFFF) == message.sequence \
                and info.timestamp_ns == message.log_time:
            index = info.frame_index
            pixel_format = info.pixel_format or pixel_format
            if info.metadata_json:
                try:
                    decoded = json.loads(info.metadata_json)
                    metadata = decoded if isinstance(decoded, dict) else {"value": decoded}
                except (ValueError, RecursionError):
                    metadata = {"metadata_json": info.metadata_json}
        return Frame(index=index, timestamp_ns=message.log_time, image=image, pixel_format=pixel_format,
                     metadata=metadata)

    def _pace(self, first, timestamp_ns):
        """Sleep until ``timestamp_ns`` is due (in slices, so ``close`` is prompt); returns the origin."""
        now = time.monotonic()
        if first is None:
            return now, timestamp_ns
        due = first[0] + (timestamp_ns - first[1]) / 1e9
        if timestamp_ns < first[1] or due < now - 1.0:
            return now, timestamp_ns             # clock went back or we fell behind: re-anchor
        while not self._closed:
            left = due - time.monotonic()
            if left <= 0:
                break
            time.sleep(min(left, 0.1))
        return first


# ----------------------------------------------------------------------------- recover

def recover(src, dst, *, overwrite=False, chunk_bytes=1 << 20, compression=None):
    """Rewrite a crashed or truncated livedic recording as a complete, indexed MCAP.

    Copies every schema, channel, metadata record and readable message of ``src``
    (in file order, with their log/publish times and sequences) into ``dst``, skipping
    corrupt chunks whose length is intact, and adds a ``livedic.recovery`` metadata
    record describing what was done. ``dst`` is written under a temporary name and
    renamed when complete.

    Parameters
    ----------
    src, dst : str or os.PathLike
    overwrite : bool
        Allow replacing an existing ``dst``.
    chunk_bytes : int
    compression : None or "lz4"

    Returns
    -------
    dict
        ``src``, ``dst``, ``messages``, ``frames``, ``results``, ``events``,
        ``message_counts`` (per topic), ``truncated``, ``src_bytes``, ``valid_bytes``,
        ``corrupt_chunks``, ``skipped_messages``, ``note``.

    Raises
    ------
    RecordingError
        ``src`` unreadable or not livedic, ``dst`` equal to ``src``, or ``dst`` exists.
    """
    from mcap.writer import LIBRARY_IDENTIFIER

    from livedic.stream.recorder import ChunkedWriter, software_version

    src_path, dst_path = os.fspath(src), os.fspath(dst)
    if os.path.realpath(src_path) == os.path.realpath(dst_path) or (
            os.path.exists(dst_path) and os.path.exists(src_path) and os.path.samefile(src_path, dst_path)):
        raise RecordingError(f"recover: destination {dst_path} is the source itself; choose another file")
    if os.path.exists(dst_path) and not overwrite:
        raise RecordingError(f"recover: {dst_path} already exists; pass overwrite=True to replace it")
    recording = _open(src_path)
    recording.summary = None                       # walk every record, whatever the index says
    recording.schemas, recording.channels = {}, {}
    tmp_path = f"{dst_path}.partial-{os.getpid()}"
    counts = Counter()
    skipped = 0
    schema_map, channel_map, kinds = {}, {}, {}
    try:
        with open(tmp_path, "xb") as out:
            writer = ChunkedWriter(out, chunk_bytes=chunk_bytes, compression=compression,
                                    library=f"livedic/{software_version()} (recovered) {LIBRARY_IDENTIFIER}")
            for kind, item in recording._linear(strict=False):
                if kind == "schema":
                    if item.id not in schema_map:
                        schema_map[item.id] = writer.writer.register_schema(item.name, item.encoding, item.data)
                elif kind == "channel":
                    if item.id in channel_map:
                        continue
                    if item.schema_id and item.schema_id not in schema_map:
                        continue
                    channel_map[item.id] = writer.writer.register_channel(
                        item.topic, item.message_encoding, schema_map.get(item.schema_id, 0), dict(item.metadata))
                    kinds[item.id] = "image" if item.topic in (rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO) else "data"
                elif kind == "metadata":
                    writer.writer.add_metadata(item[0], item[1])
                else:
                    if item.channel_id not in channel_map:
                        skipped += 1
                        continue
                    writer.add(kinds[item.channel_id], channel_map[item.channel_id], item.log_time,
                               bytes(item.data), publish_time=item.publish_time, sequence=item.sequence)
                    counts[recording.channels[item.channel_id].topic] += 1
            info = recording.info
            writer.writer.add_metadata(rs.RECOVERY_METADATA_NAME, {
                "source": os.path.abspath(src_path), "source_bytes": str(info.size_bytes),
                "valid_bytes": str(info.valid_bytes), "truncated": "true" if info.truncated else "false",
                "messages": str(sum(counts.values())), "corrupt_chunks": str(info.corrupt_chunks),
                "recovered_at": datetime.now(timezone.utc).isoformat()})
            writer.finish()
            out.flush()
            os.fsync(out.fileno())
        if os.path.exists(dst_path) and not overwrite:
            raise RecordingError(f"recover: {dst_path} appeared while recovering; the result is in {tmp_path}")
        os.replace(tmp_path, dst_path)
    except BaseException:
        if os.path.exists(tmp_path):
            os.remove(tmp_path)
        raise
    info = recording.info
    note = ""
    if info.truncated:
        note = (f"{recording.name} was truncated at byte {info.valid_bytes} of {info.size_bytes}; "
                f"{sum(counts.values())} messages recovered")
    if info.corrupt_chunks:
        note += ("; " if note else "") + f"{info.corrupt_chunks} corrupt chunk(s) skipped"
    return {"src": src_path, "dst": dst_path, "messages": sum(counts.values()),
            "frames": counts[rs.TOPIC_IMAGE], "results": counts[rs.TOPIC_RESULTS],
            "events": counts[rs.TOPIC_EVENTS], "message_counts": dict(counts),
            "truncated": info.truncated, "src_bytes": info.size_bytes, "valid_bytes": info.valid_bytes,
            "corrupt_chunks": info.corrupt_chunks, "skipped_messages": skipped, "note": note}
