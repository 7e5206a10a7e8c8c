"""Read livedic recordings (MCAP): replay frames, read results, strain, extensometers, force, events and
metadata, recover crashes.

This module holds ``Recording`` and the ``read_*`` functions; ``source`` replays frames
(``McapSource``, ``FrameReader``), ``recover`` rewrites crashed files, ``errors`` and ``records``
hold what they raise and return; the format is in ``schema``. A file with a valid summary is
read through its index (only the chunks of the wanted topics: ``read_results`` never touches
an image); otherwise a recovery scan reads records one by one until the data ends, and
``RecordingInfo.truncated`` says so (not an error; one note is logged for people).

Guarantees on any file, however damaged or hostile: bounded reads and decompression (nothing
over 1 GiB), chunk CRCs verified, payloads decoded only as protobuf or JSON, and the only
exception is ``RecordingError`` (a ``ValueError``, one line naming the file and the problem)
or one of its subclasses ``NotMcap``, ``NotLivedic``, ``CorruptRecording``,
``NoSessionMetadata``; ``McapSource`` raises ``RecordingSourceError`` (also an
``acquire.base.SourceError``) with the specific error as its ``__cause__``. Details:
docs/guide/recording-format.md ("Opening a recording", "What the reader guarantees").

Examples
--------
>>> from livedic.acquire.recording.reader import Recording, read_results   # doctest: +SKIP
>>> from livedic.acquire.recording.source import McapSource                 # doctest: +SKIP
>>> with McapSource("session.mcap", realtime=False) as source:  # doctest: +SKIP
...     for frame in source:
...         print(frame.index, frame.image.shape)
>>> results = read_results("session.mcap")                       # doctest: +SKIP
>>> results[0].u, results[0].ok                                   # doctest: +SKIP
>>> strain = read_strain_fields("session.mcap")                  # doctest: +SKIP
>>> samples = read_extensometer_samples("session.mcap")          # doctest: +SKIP
>>> force = read_force_samples("session.mcap")                   # doctest: +SKIP
>>> recording = Recording("session.mcap")                         # doctest: +SKIP
>>> n = sum(1 for _ in recording.results()); recording.info.truncated   # doctest: +SKIP
"""

from __future__ import annotations

import logging
import os
from collections import Counter
from collections.abc import Callable, Collection, Iterator
from typing import Any, BinaryIO, TypeVar, cast

from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, Header, McapRecord, Message, Metadata, Schema
from mcap.summary import Summary

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.recording.container import (MAGIC, Damaged, RecordScan, ScanEnd, open_chunk, parse_record,
                                                 read_record, read_record_at, read_summary)
from livedic.acquire.recording.errors import CorruptRecording, NoSessionMetadata, NotLivedic, NotMcap, RecordingError
from livedic.acquire.recording.metadata import metadata_from_strings
from livedic.acquire.recording.records import (RecordedEvent, RecordedExtensometerSample, RecordedForceSample,
                                               RecordedResults, RecordedStrain, RecordingInfo, frame_readings,
                                               recorded_results, recorded_strain)
from livedic.dic.strain.extensometer import ExtensometerReadings

__all__ = ["Recording", "inspect_recording", "iter_results", "read_events", "read_extensometer_samples",
           "read_force_samples", "read_results", "read_session", "read_strain_fields"]

log = logging.getLogger(__name__)

_HEAD_BYTES = 9                         # opcode (1) and length (8) before every record body
_MAX_HEADER_BYTES = 1 << 20
_T = TypeVar("_T")
_DATA_RECORDS = frozenset({Opcode.HEADER, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.CHUNK,
                           Opcode.METADATA})


# ----------------------------------------------------------------------------- the file reader

class Recording:
    """A recording opened for reading: header checked, summary loaded when it has a sound one.

    Parameters
    ----------
    path : str or os.PathLike
    livedic_only : bool
        Refuse (``NotLivedic``) an MCAP file livedic did not write.

    Each pass (``results``, ``events``, ``messages`` ...) reads the file again, by the
    index when there is a valid one, else record by record, and updates ``info``
    (``RecordingInfo``: ``truncated``, ``message_counts`` ...).

    Raises
    ------
    RecordingError
        Missing, unreadable, ``NotMcap``, ``CorruptRecording`` header, ``NotLivedic``.
    """

    def __init__(self, path: str | os.PathLike[str], *, livedic_only: bool = True) -> None:
        self.path = os.fspath(path)
        self.name = self.path
        try:
            with open(self.path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                self._check_start(f, size)
                self.summary: Summary | None
                self.summary, self.summary_problem = read_summary(f, size, self.data_start)
        except FileNotFoundError:
            raise RecordingError(f"{self.name} does not exist") from None
        except IsADirectoryError:
            raise RecordingError(f"{self.name} is a directory, not an MCAP recording") from None
        except OSError as error:
            raise RecordingError(f"{self.name} cannot be read ({error.strerror or error})") from None
        indexed = self.summary is not None
        self.info = RecordingInfo(self.path, size, indexed=indexed, library=self.library,
                                  valid_bytes=size if indexed else self.data_start)
        self.schemas: dict[int, Schema] = dict(self.summary.schemas) if self.summary is not None else {}
        self.channels: dict[int, Channel] = dict(self.summary.channels) if self.summary is not None else {}
        self.metadata_names: set[str] = ({index.name for index in self.summary.metadata_indexes}
                                         if self.summary is not None else set())
        self.probe_metadata: dict[str, dict[str, str]] = {}
        self.probe_session: Message | None = None
        if not indexed:
            self._probe()
        self.info.is_livedic = self._is_livedic()
        if livedic_only and not self.info.is_livedic:
            raise NotLivedic(f"{self.name} was not written by livedic (no {rs.TOPIC_IMAGE} RawImage channel)")

    # -- opening checks

    def _check_start(self, f: BinaryIO, size: int) -> None:
        head = f.read(len(MAGIC))
        if size == 0:
            raise NotMcap(f"{self.name} is empty (0 bytes), not an MCAP recording")
        if head != MAGIC:
            if len(head) < len(MAGIC) and MAGIC.startswith(head):
                raise NotMcap(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
            raise NotMcap(f"{self.name} is not an MCAP file (bad magic bytes {head[:8]!r})")
        record = f.read(_HEAD_BYTES)
        if len(record) < _HEAD_BYTES:
            raise NotMcap(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
        opcode, length = record[0], int.from_bytes(record[1:], "little")
        if opcode != Opcode.HEADER:
            raise NotMcap(f"{self.name} is not a valid MCAP file (first record has opcode {opcode:#04x}, "
                          f"not a header)")
        if length > size - len(MAGIC) - _HEAD_BYTES:
            raise NotMcap(f"{self.name} is truncated inside the MCAP header ({size} bytes)")
        if length > _MAX_HEADER_BYTES:
            raise CorruptRecording(f"{self.name} is corrupt: its header record claims {length} bytes")
        try:
            header = cast(Header, parse_record(Opcode.HEADER, f.read(length)))
        except Damaged as bad:
            raise CorruptRecording(f"{self.name} is corrupt: bad header record ({bad})") from None
        self.profile, self.library = header.profile, header.library
        self.data_start = len(MAGIC) + _HEAD_BYTES + length

    def _probe(self) -> None:
        """Recovery-scan the start of the file (up to the first chunk) for channels and metadata."""
        scratch = RecordingInfo(self.path, self.info.size_bytes)
        try:
            for record in self._scan(strict=False, first_chunk_only=True, info=scratch):
                if isinstance(record, Metadata):
                    self.metadata_names.add(record.name)
                    self.probe_metadata.setdefault(record.name, record.metadata)
                elif isinstance(record, Message) and self.probe_session is None \
                        and self.channels[record.channel_id].topic == rs.TOPIC_SESSION:
                    self.probe_session = record
        except RecordingError:
            pass

    def _is_livedic(self) -> bool:
        if self.library.startswith("livedic") or rs.METADATA_NAME in self.metadata_names:
            return True
        return any(self.schema_name(channel) == rs.RAW_IMAGE_SCHEMA for channel in self.channels.values()
                   if channel.topic == rs.TOPIC_IMAGE)

    def schema_name(self, channel: Channel) -> str | None:
        """Name of the protobuf schema of ``channel`` (an ``mcap.records.Channel``), None if not protobuf."""
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None and channel.message_encoding == "protobuf" else None

    def forget_index(self) -> None:
        """Read the file record by record from now on, whatever its index says (``recover``)."""
        self.summary = None
        self.schemas, self.channels = {}, {}

    # -- passes

    def _open_file(self) -> BinaryIO:
        try:
            return open(self.path, "rb")
        except OSError as error:
            raise RecordingError(f"{self.name} cannot be read any more ({error.strerror or error})") from None

    def _corrupt(self, what: str, offset: int, bad: object) -> CorruptRecording:
        return CorruptRecording(f"{self.name} is corrupt: {what} at byte {offset} ({bad}); "
                                f"`recover` can rewrite what is readable")

    def _scan(self, *, strict: bool = True, first_chunk_only: bool = False,
              info: RecordingInfo | None = None) -> Iterator[McapRecord]:
        """Recovery scan from the start: yields mcap ``Schema``, ``Channel``, ``Metadata`` and ``Message`` records.

        Updates ``info`` (default ``self.info``): ``valid_bytes``, ``truncated``,
        ``corrupt_chunks``. With ``strict`` a corrupt record raises; otherwise a corrupt
        record whose length is intact is skipped (and counted) and the scan goes on.
        """
        info = self.info if info is None else info
        with self._open_file() as f:
            scan = RecordScan(f, self.data_start, os.fstat(f.fileno()).st_size)
            info.truncated = True                      # until the scan reaches the DataEnd record
            for offset, opcode, length in scan:
                info.valid_bytes = offset + _HEAD_BYTES + length
                if opcode not in _DATA_RECORDS:
                    continue
                try:
                    records = _data_records(f, opcode, length)
                except Damaged as bad:
                    if strict:
                        what = "a chunk" if opcode == Opcode.CHUNK else f"a record (opcode {opcode:#04x})"
                        raise self._corrupt(what, offset, bad) from None
                    info.corrupt_chunks += 1
                    continue
                for record in records:
                    if self._register(record, strict, offset):
                        yield record
                if opcode == Opcode.CHUNK and first_chunk_only:
                    return
            info.valid_bytes = scan.valid_bytes
            info.truncated = not cast(ScanEnd, scan.stop).complete        # set once the scan has run
            if scan.claimed and strict:
                raise self._corrupt("a record", scan.valid_bytes, f"it claims {scan.claimed} bytes")
        if info.truncated and not first_chunk_only:
            info.note = (f"{self.name} is truncated (the recording did not finish: crash, kill or disk full); "
                         f"read {sum(info.message_counts.values())} messages "
                         f"({info.frames} frames) from the first {info.valid_bytes} of {info.size_bytes} bytes")

    def _register(self, record: McapRecord, strict: bool, offset: int) -> bool:
        """Remember schemas and channels; False for a record that refers to an unknown one (corrupt if strict)."""
        if isinstance(record, Schema):
            self.schemas[record.id] = record
        elif isinstance(record, Channel):
            if record.schema_id and record.schema_id not in self.schemas:
                if strict:
                    raise self._corrupt("a channel", offset, f"schema {record.schema_id} is unknown")
                return False
            self.channels[record.id] = record
        elif isinstance(record, Message) and record.channel_id not in self.channels:
            if strict:
                raise self._corrupt("a message", offset, f"channel {record.channel_id} is unknown")
            return False
        return True

    def _indexed(self, channel_ids: set[int] | None) -> Iterator[Message]:
        """Messages of ``channel_ids`` (None: all) through the chunk index, in file order."""
        summary = self.summary
        if summary is None:              # only called while there is an index
            return
        with self._open_file() as f:
            for index in summary.chunk_indexes:
                held = index.message_index_offsets.keys()
                if channel_ids is not None and held and not channel_ids & held:
                    continue
                offset = index.chunk_start_offset
                try:
                    records = open_chunk(cast(Chunk, read_record_at(f, offset, index.chunk_length, Opcode.CHUNK)))
                except Damaged as bad:
                    raise self._corrupt("a chunk", offset, bad) from None
                for record in records:
                    if isinstance(record, Message):
                        if record.channel_id not in self.channels:
                            raise self._corrupt("a message", offset, f"channel {record.channel_id} is unknown")
                        if channel_ids is None or record.channel_id in channel_ids:
                            yield record
                    elif isinstance(record, Channel):
                        self.channels.setdefault(record.id, record)
                    elif isinstance(record, Schema):
                        self.schemas.setdefault(record.id, record)

    def messages(self, topics: Collection[str] | None = None) -> Iterator[tuple[Channel, Message]]:
        """Yield ``(channel, message)`` (mcap records) for ``topics`` (None: all), in file order, by the best path."""
        info = self.info
        counts: Counter[str] = Counter()
        info.message_counts = counts
        if self.summary is not None:
            ids = None if topics is None else {cid for cid, ch in self.channels.items() if ch.topic in topics}
            source: Iterator[Message] = self._indexed(ids)
        else:
            source = (record for record in self._scan() if isinstance(record, Message))
        for message in source:
            channel = self.channels[message.channel_id]
            counts[channel.topic] += 1
            if topics is None or channel.topic in topics:
                if info.start_ns is None or message.log_time < info.start_ns:
                    info.start_ns = message.log_time
                if info.end_ns is None or message.log_time > info.end_ns:
                    info.end_ns = message.log_time
                yield channel, message
        if info.truncated and info.note:
            log.warning("note: %s", info.note)
        elif self.summary_problem and not info.note:
            info.note = f"{self.name}: {self.summary_problem}; it was read record by record instead"
            log.warning("note: %s", info.note)

    def count(self, topic: str) -> int:
        """How many messages ``topic`` holds: from the summary's statistics, else by reading the file.

        A file cut short has no summary: its messages are counted by the recovery scan (a pass over
        the whole file, as ``results`` makes).
        """
        statistics = self.summary.statistics if self.summary is not None else None
        if statistics is not None:
            return sum(count for channel_id, count in statistics.channel_message_counts.items()
                       if channel_id in self.channels and self.channels[channel_id].topic == topic)
        return sum(1 for _ in self.messages({topic}))

    def records(self, *, strict: bool = True) -> Iterator[McapRecord]:
        """Every schema, channel, metadata and message record in file order, by the recovery scan."""
        return self._scan(strict=strict)

    # -- content

    def session_strings(self) -> dict[str, str] | None:
        """The ``livedic.session`` string map (Metadata record, else the first session message), or None."""
        if self.summary is not None:
            with self._open_file() as f:
                for index in self.summary.metadata_indexes:
                    if index.name != rs.METADATA_NAME:
                        continue
                    try:
                        record = read_record_at(f, index.offset, index.length, Opcode.METADATA)
                        return cast(Metadata, record).metadata       # read_record_at checked the opcode
                    except Damaged as bad:
                        raise self._corrupt("the session metadata", index.offset, bad) from None
            for _, message in self.messages({rs.TOPIC_SESSION}):
                return self._decode_session(message)
            return None
        if rs.METADATA_NAME in self.probe_metadata:
            return self.probe_metadata[rs.METADATA_NAME]
        if self.probe_session is not None:
            return self._decode_session(self.probe_session)
        return None

    def _decode_session(self, message: Message) -> dict[str, str]:
        try:
            return dict(rs.Session.FromString(message.data).metadata)
        except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
            raise CorruptRecording(f"{self.name} is corrupt: undecodable session message "
                                   f"({type(error).__name__})") from None

    def session(self) -> dict[str, Any]:
        """Session metadata, with non-string values decoded from JSON (``NoSessionMetadata`` if none)."""
        strings = self.session_strings()
        if strings is None:
            raise NoSessionMetadata(f"{self.name} has no session metadata ({rs.METADATA_NAME})")
        return metadata_from_strings(strings)

    def results(self) -> Iterator[RecordedResults]:
        """Yield ``RecordedResults`` per frame from ``/dic/results``, in recorded order."""
        for channel, message in self.messages({rs.TOPIC_RESULTS}):
            if self.schema_name(channel) != rs.FRAME_RESULTS_SCHEMA:
                continue
            try:
                values = wire.decode_results(message.data)
            except wire.WireError as bad:
                raise CorruptRecording(f"{self.name} is corrupt: results message at log time {message.log_time} "
                                       f"({bad})") from None
            yield recorded_results(values, message.publish_time)

    def _decoded(self, topic: str, schema: str, decode: Callable[[bytes], _T], what: str) -> Iterator[_T]:
        """Yield ``decode(message bytes)`` for each message of ``topic`` with ``schema``; CorruptRecording if bad."""
        for channel, message in self.messages({topic}):
            if self.schema_name(channel) != schema:
                continue
            try:
                value = decode(message.data)
            except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
                raise CorruptRecording(f"{self.name} is corrupt: {what} message at log time {message.log_time} "
                                       f"({error if isinstance(error, wire.WireError) else type(error).__name__})"
                                       ) from None
            yield value

    def strain_fields(self) -> Iterator[RecordedStrain]:
        """Yield ``RecordedStrain`` per frame from ``/dic/strain`` (nothing for a recording without strain)."""
        yield from self._decoded(rs.TOPIC_STRAIN, rs.STRAIN_FIELD_SCHEMA,
                                 lambda data: recorded_strain(rs.StrainField.FromString(data)), "strain")

    def extensometer_samples(self) -> Iterator[RecordedExtensometerSample]:
        """Yield ``RecordedExtensometerSample`` from ``/dic/extensometers``: per frame, one per extensometer."""
        for sample in self._decoded(rs.TOPIC_EXTENSOMETERS, rs.EXTENSOMETER_SAMPLE_SCHEMA,
                                    rs.ExtensometerSample.FromString, "extensometer"):
            yield RecordedExtensometerSample(
                frame_index=sample.frame_index, timestamp_ns=sample.timestamp_ns, name=sample.name,
                l0_px=sample.l0_px, l_px=sample.l_px, eng_strain=sample.eng_strain, true_strain=sample.true_strain,
                ok=sample.ok, status=sample.status,
                # L0 is never 0 for a real extensometer: 0 (proto3's "not set") means a 2D recording
                l0_mm=sample.l0_mm if sample.l0_mm else None, l_mm=sample.l_mm if sample.l0_mm else None)

    def extensometer_readings(self) -> Iterator[tuple[int, int, ExtensometerReadings]]:
        """Yield ``(frame_index, timestamp_ns, dic.strain.extensometer.ExtensometerReadings)`` per recorded frame.

        The samples of one frame (consecutive messages with the same frame index) gathered
        in recorded order, as ``dic.strain.extensometer.read_extensometers`` returns them.
        """
        frame: list[RecordedExtensometerSample] = []
        for sample in self.extensometer_samples():
            if frame and (sample.frame_index, sample.timestamp_ns) != (frame[0].frame_index, frame[0].timestamp_ns):
                yield frame[0].frame_index, frame[0].timestamp_ns, frame_readings(frame)
                frame = []
            frame.append(sample)
        if frame:
            yield frame[0].frame_index, frame[0].timestamp_ns, frame_readings(frame)

    def force_samples(self) -> Iterator[RecordedForceSample]:
        """Yield ``RecordedForceSample`` from ``/machine/force``: one per tracked frame, none in older recordings."""
        for sample in self._decoded(rs.TOPIC_FORCE, rs.FORCE_SAMPLE_SCHEMA, rs.ForceSample.FromString, "force"):
            yield RecordedForceSample(frame_index=sample.frame_index, timestamp_ns=sample.timestamp_ns,
                                      force_N=sample.force_N, stress_MPa=sample.stress_MPa, ok=sample.ok,
                                      source=sample.source)

    def events(self) -> list[RecordedEvent]:
        """List of ``RecordedEvent`` from ``/livedic/events``."""
        out: list[RecordedEvent] = []
        for _, message in self.messages({rs.TOPIC_EVENTS}):
            try:
                event = rs.Event.FromString(message.data)
            except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
                raise CorruptRecording(f"{self.name} is corrupt: undecodable event at log time "
                                       f"{message.log_time} ({type(error).__name__})") from None
            out.append(RecordedEvent(event.timestamp_ns, event.kind, event.message, event.level))
        return out


def _data_records(f: BinaryIO, opcode: int, length: int) -> list[McapRecord]:
    """The records a data-section record at ``f``'s position holds: a chunk's contents, or the record itself."""
    if opcode == Opcode.HEADER:
        raise Damaged("a second header record")
    record = read_record(f, opcode, length)
    records = open_chunk(record) if isinstance(record, Chunk) else [record]
    if any(isinstance(record, Schema) and record.id == 0 for record in records):
        raise Damaged("schema id 0")
    return records


# ----------------------------------------------------------------------------- public readers

def read_session(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Session metadata of a recording, with non-string values decoded from JSON.

    Raises
    ------
    RecordingError
        Not a readable livedic recording, or ``NoSessionMetadata``.
    """
    return Recording(path).session()


def iter_results(path: str | os.PathLike[str]) -> Iterator[RecordedResults]:
    """Yield ``RecordedResults`` per frame from ``/dic/results``, in recorded order."""
    yield from Recording(path).results()


def read_results(path: str | os.PathLike[str]) -> list[RecordedResults]:
    """List of ``RecordedResults``, one per recorded frame (see ``iter_results``)."""
    return list(iter_results(path))


def read_strain_fields(path: str | os.PathLike[str]) -> list[RecordedStrain]:
    """List of ``RecordedStrain``, one per frame recorded with strain (empty for older recordings)."""
    return list(Recording(path).strain_fields())


def read_extensometer_samples(path: str | os.PathLike[str]) -> list[RecordedExtensometerSample]:
    """List of ``RecordedExtensometerSample``: per frame, one per extensometer (empty without extensometers)."""
    return list(Recording(path).extensometer_samples())


def read_force_samples(path: str | os.PathLike[str]) -> list[RecordedForceSample]:
    """List of ``RecordedForceSample``, one per tracked frame (empty for recordings without force)."""
    return list(Recording(path).force_samples())


def read_events(path: str | os.PathLike[str]) -> list[RecordedEvent]:
    """List of ``RecordedEvent`` from ``/livedic/events``."""
    return Recording(path).events()


def inspect_recording(path: str | os.PathLike[str]) -> RecordingInfo:
    """``RecordingInfo`` for any MCAP file: how it reads, what it holds, whether it is truncated.

    Reads every message (the recovery scan, or the index); raises ``RecordingError``
    only when the file is not MCAP or is corrupt.
    """
    recording = Recording(path, livedic_only=False)
    for _ in recording.messages():
        pass
    return recording.info
