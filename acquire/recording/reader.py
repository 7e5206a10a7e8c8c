"""Read livedic recordings (MCAP): replay frames, read results, strain, extensometers, force, events and
metadata, recover crashes.

The format lives in ``livedic.acquire.recording``: ``schema`` (topics, schemas,
codecs), ``container`` (MCAP records on the ``mcap`` library, read within bounds,
written in livedic's chunk layout), ``writer`` (live sessions) and this module (the
readers, ``recover``).

Every reader takes the fastest safe path:

* **Indexed.** The file ends with the MCAP magic, its footer parses, and the summary
  (schemas, channels, chunk and metadata indexes) passes its CRC and bounds checks:
  only the chunks holding the wanted topics are read (``read_results`` never touches
  an image chunk; the recorder keeps image and data chunks apart).
* **Recovery scan.** Otherwise (the recorder was killed, the disk filled up, the
  summary is damaged) records are read one by one from the start, as mcap's
  non-seeking reader does, until the data ends: at a partial record (where the
  writer died), at zero bytes, at the end of the file or at the DataEnd record.
  A truncated file is not an error: ``RecordingInfo.truncated`` says so (the
  ``info`` of a ``Recording`` or an ``McapSource`` after a pass, or
  ``inspect_recording``), and the reader logs one note for people (logger
  ``livedic.acquire.recording.reader``) saying how many messages it recovered.

What the reader guarantees on any file, however damaged or hostile: no record over
1 GiB is read and no chunk is decompressed beyond the size it claims (itself at
most 1 GiB), so garbage cannot allocate gigabytes or hang; chunk CRCs are
verified; payloads are protobuf or JSON only, nothing from a file is ever
unpickled or evaluated; and the only exceptions that come out are
``RecordingError`` (a ``ValueError``) with one line naming the file and the
problem. Its subclasses say which problem, for callers that act on it:
``NotMcap`` (empty, not MCAP, cut inside the header), ``NotLivedic`` (an MCAP
file from another program), ``CorruptRecording`` (a damaged record; ``recover``
can rewrite what is readable), ``NoSessionMetadata``. ``McapSource`` raises
``RecordingSourceError``, also an ``acquire.base.SourceError``, with the specific
error as its ``__cause__``.

Examples
--------
>>> from livedic.acquire.recording.reader import McapSource, Recording, read_results   # doctest: +SKIP
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

import json
import logging
import os
import time
from collections import Counter
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone

import numpy as np
from mcap.opcode import Opcode
from mcap.records import Channel, Message, Metadata, Schema

from livedic.acquire.recording import schema as rs
from livedic.acquire.atomic_file import AtomicFile
from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.acquire.recording.container import (MAGIC, ChunkedWriter, Damaged, RecordScan, library_name, open_chunk,
                                                 parse_record, read_record, read_record_at, read_summary)
from livedic.dic.strain.extensometer import ExtensometerReadings
from livedic.dic.result import Measurement

__all__ = ["CorruptRecording", "FrameReader", "McapSource", "NoSessionMetadata", "NotLivedic", "NotMcap",
           "RecordedEvent", "RecordedExtensometerSample", "RecordedForceSample", "RecordedResults", "RecordedStrain",
           "Recording", "RecordingError", "RecordingInfo", "RecordingSourceError", "inspect_recording", "iter_results",
           "read_events", "read_extensometer_samples", "read_force_samples", "read_results", "read_session",
           "read_strain_fields", "recover"]

log = logging.getLogger(__name__)

_HEAD_BYTES = 9                         # opcode (1) and length (8) before every record body
_MAX_HEADER_BYTES = 1 << 20
_DATA_RECORDS = frozenset({Opcode.HEADER, Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE, Opcode.CHUNK,
                           Opcode.METADATA})


# ----------------------------------------------------------------------------- errors

class RecordingError(ValueError):
    """A recording that cannot be read as asked; the message is one line naming the file."""


class NotMcap(RecordingError):
    """Not an MCAP file: empty, other content, or cut inside the MCAP header."""


class NotLivedic(RecordingError):
    """An MCAP file that livedic did not write (no ``/camera/image`` RawImage channel)."""


class CorruptRecording(RecordingError):
    """A record, chunk or message that does not decode; ``recover`` can rewrite what is readable."""


class NoSessionMetadata(RecordingError):
    """A livedic recording without its ``livedic.session`` metadata."""


class RecordingSourceError(SourceError, RecordingError):
    """``RecordingError`` raised by ``McapSource``: also a ``SourceError`` for the live pipeline."""


# ----------------------------------------------------------------------------- what readers return

_MEASURED = ("x", "y", "u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations")


def _measured(name):
    return property(lambda self: getattr(self.measurement, name), doc=f"``measurement.{name}``")


@dataclass(frozen=True)
class RecordedResults:
    """One frame's results as recorded on ``/dic/results``.

    ``measurement`` is what the tracker measured, as a ``dic.result.Measurement``
    (``evaluations`` is not recorded: None); its arrays are also attributes of the
    record: ``x, y, u, v, zncc, ok`` and ``status, ux, uy, vx, vy, iterations``
    (None when they were not recorded). Arrays have shape (N,): ``point_id`` uint32,
    ``ok`` bool, ``status``/``iterations`` int32/uint32, the rest float64. They may
    be read-only views into the file data.
    """
    frame_index: int
    timestamp_ns: int
    point_id: np.ndarray
    measurement: Measurement
    method: str = ""
    processing_ns: int = 0
    latency_ns: int = 0
    reference_frame_index: int = 0
    dropped_frames: int = 0
    publish_time_ns: int = 0            # host clock when the recorder wrote it

    x = _measured("x")
    y = _measured("y")
    u = _measured("u")
    v = _measured("v")
    zncc = _measured("zncc")
    ok = _measured("ok")
    status = _measured("status")
    ux = _measured("ux")
    uy = _measured("uy")
    vx = _measured("vx")
    vy = _measured("vy")
    iterations = _measured("iterations")


def _recorded_results(values, publish_time_ns):
    """``RecordedResults`` from ``schema.decode_results`` values."""
    return RecordedResults(
        frame_index=values["frame_index"], timestamp_ns=values["timestamp_ns"], point_id=values["point_id"],
        measurement=Measurement(**{name: values[name] for name in _MEASURED}), method=values["method"],
        processing_ns=values["processing_ns"], latency_ns=values["latency_ns"],
        reference_frame_index=values["reference_frame_index"], dropped_frames=values["dropped_frames"],
        publish_time_ns=publish_time_ns)


@dataclass(frozen=True)
class RecordedStrain:
    """One frame's strain field as recorded on ``/dic/strain`` (``livedic.StrainField``).

    Arrays have shape (N,), in the order of the frame's ``/dic/results`` points:
    ``point_id`` uint32, ``status`` int32 (``dic.strain.StrainStatus`` codes), the
    strains float64 (NaN where ``status`` is not 0). ``window`` is 0 when it was not
    recorded.
    """
    frame_index: int
    timestamp_ns: int
    point_id: np.ndarray
    exx: np.ndarray
    eyy: np.ndarray
    exy: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    status: np.ndarray
    measure: str
    window: int
    vsg_px: float

    @property
    def ok(self):
        return self.status == 0


@dataclass(frozen=True)
class RecordedExtensometerSample:
    """One extensometer's reading in one frame, as recorded on ``/dic/extensometers``.

    ``l_px``, ``eng_strain`` and ``true_strain`` are NaN where ``ok`` is False;
    ``status`` is a ``dic.strain.extensometer.ExtensometerStatus`` code.
    """
    frame_index: int
    timestamp_ns: int
    name: str
    l0_px: float
    l_px: float
    eng_strain: float
    true_strain: float
    ok: bool
    status: int


@dataclass(frozen=True)
class RecordedForceSample:
    """The machine's force on one tracked frame, as recorded on ``/machine/force``.

    ``force_N`` is NaN (and ``ok`` False) where the load had no value for the frame;
    ``stress_MPa`` (engineering) is NaN where the session had no cross-section;
    ``source`` is the load URI.
    """
    frame_index: int
    timestamp_ns: int
    force_N: float
    stress_MPa: float
    ok: bool
    source: str


_STRAIN_FLOATS = ("exx", "eyy", "exy", "e1", "e2")


def _recorded_strain(message):
    """``RecordedStrain`` from a decoded ``livedic.StrainField``; WireError when its arrays differ in length."""
    arrays = {"point_id": np.array(message.point_id, dtype=np.uint32),
              "status": np.array(message.status, dtype=np.int32)}
    arrays.update({name: np.array(getattr(message, name), dtype=np.float64) for name in _STRAIN_FLOATS})
    lengths = {name: len(array) for name, array in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise rs.WireError("strain arrays differ in length: "
                           + ", ".join(f"{name} {n}" for name, n in lengths.items()))
    return RecordedStrain(frame_index=message.frame_index, timestamp_ns=message.timestamp_ns, measure=message.measure,
                          window=message.window, vsg_px=message.vsg_px, **arrays)


def _readings(samples):
    """``dic.strain.extensometer.ExtensometerReadings`` of one frame's samples, in recorded order."""
    return ExtensometerReadings(names=tuple(s.name for s in samples),
                                l0_px=np.array([s.l0_px for s in samples], dtype=np.float64),
                                length_px=np.array([s.l_px for s in samples], dtype=np.float64),
                                eng_strain=np.array([s.eng_strain for s in samples], dtype=np.float64),
                                true_strain=np.array([s.true_strain for s in samples], dtype=np.float64),
                                status=np.array([s.status for s in samples], dtype=np.int32))


@dataclass(frozen=True)
class RecordedEvent:
    """A note from ``/livedic/events``."""
    timestamp_ns: int
    kind: str
    message: str
    level: str


@dataclass
class RecordingInfo:
    """What a reader found in a recording (see ``inspect_recording``); updated by each pass over it."""
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

    def __init__(self, path, *, livedic_only=True):
        self.path = os.fspath(path)
        self.name = self.path
        try:
            with open(self.path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                self._check_start(f, size)
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
        self.schemas = dict(self.summary.schemas) if indexed else {}
        self.channels = dict(self.summary.channels) if indexed else {}
        self.metadata_names = {index.name for index in self.summary.metadata_indexes} if indexed else set()
        self.probe_metadata, self.probe_session = {}, None
        if not indexed:
            self._probe()
        self.info.is_livedic = self._is_livedic()
        if livedic_only and not self.info.is_livedic:
            raise NotLivedic(f"{self.name} was not written by livedic (no {rs.TOPIC_IMAGE} RawImage channel)")

    # -- opening checks

    def _check_start(self, f, size):
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
            header = parse_record(Opcode.HEADER, f.read(length))
        except Damaged as bad:
            raise CorruptRecording(f"{self.name} is corrupt: bad header record ({bad})") from None
        self.profile, self.library = header.profile, header.library
        self.data_start = len(MAGIC) + _HEAD_BYTES + length

    def _probe(self):
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

    def _is_livedic(self):
        if self.library.startswith("livedic") or rs.METADATA_NAME in self.metadata_names:
            return True
        return any(self.schema_name(channel) == rs.RAW_IMAGE_SCHEMA for channel in self.channels.values()
                   if channel.topic == rs.TOPIC_IMAGE)

    def schema_name(self, channel):
        """Name of the protobuf schema of ``channel`` (an ``mcap.records.Channel``), None if not protobuf."""
        schema = self.schemas.get(channel.schema_id)
        return schema.name if schema is not None and channel.message_encoding == "protobuf" else None

    def forget_index(self):
        """Read the file record by record from now on, whatever its index says (``recover``)."""
        self.summary = None
        self.schemas, self.channels = {}, {}

    # -- passes

    def _open_file(self):
        try:
            return open(self.path, "rb")
        except OSError as error:
            raise RecordingError(f"{self.name} cannot be read any more ({error.strerror or error})") from None

    def _corrupt(self, what, offset, bad):
        return CorruptRecording(f"{self.name} is corrupt: {what} at byte {offset} ({bad}); "
                                f"`recover` can rewrite what is readable")

    def _scan(self, *, strict=True, first_chunk_only=False, info=None):
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
            info.truncated = not scan.stop.complete
            if scan.claimed and strict:
                raise self._corrupt("a record", scan.valid_bytes, f"it claims {scan.claimed} bytes")
        if info.truncated and not first_chunk_only:
            info.note = (f"{self.name} is truncated (the recording did not finish: crash, kill or disk full); "
                         f"read {sum(info.message_counts.values())} messages "
                         f"({info.frames} frames) from the first {info.valid_bytes} of {info.size_bytes} bytes")

    def _register(self, record, strict, offset):
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

    def _indexed(self, channel_ids):
        """Messages of ``channel_ids`` (None: all) through the chunk index, in file order."""
        with self._open_file() as f:
            for index in self.summary.chunk_indexes:
                held = index.message_index_offsets.keys()
                if channel_ids is not None and held and not channel_ids & held:
                    continue
                offset = index.chunk_start_offset
                try:
                    records = open_chunk(read_record_at(f, offset, index.chunk_length, Opcode.CHUNK))
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

    def messages(self, topics=None):
        """Yield ``(channel, message)`` (mcap records) for ``topics`` (None: all), in file order, by the best path."""
        info = self.info
        counts = Counter()
        info.message_counts = counts
        if self.summary is not None:
            ids = None if topics is None else {cid for cid, ch in self.channels.items() if ch.topic in topics}
            source = self._indexed(ids)
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

    def count(self, topic):
        """How many messages ``topic`` holds: from the summary's statistics, else by reading the file.

        A file cut short has no summary: its messages are counted by the recovery scan (a pass over
        the whole file, as ``results`` makes).
        """
        statistics = self.summary.statistics if self.summary is not None else None
        if statistics is not None:
            return sum(count for channel_id, count in statistics.channel_message_counts.items()
                       if channel_id in self.channels and self.channels[channel_id].topic == topic)
        return sum(1 for _ in self.messages({topic}))

    def records(self, *, strict=True):
        """Every schema, channel, metadata and message record in file order, by the recovery scan."""
        return self._scan(strict=strict)

    # -- content

    def session_strings(self):
        """The ``livedic.session`` string map (Metadata record, else the first session message), or None."""
        if self.summary is not None:
            with self._open_file() as f:
                for index in self.summary.metadata_indexes:
                    if index.name != rs.METADATA_NAME:
                        continue
                    try:
                        return read_record_at(f, index.offset, index.length, Opcode.METADATA).metadata
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

    def _decode_session(self, message):
        try:
            return dict(rs.Session.FromString(message.data).metadata)
        except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
            raise CorruptRecording(f"{self.name} is corrupt: undecodable session message "
                                   f"({type(error).__name__})") from None

    def session(self):
        """Session metadata, with non-string values decoded from JSON (``NoSessionMetadata`` if none)."""
        strings = self.session_strings()
        if strings is None:
            raise NoSessionMetadata(f"{self.name} has no session metadata ({rs.METADATA_NAME})")
        return rs.metadata_from_strings(strings)

    def results(self):
        """Yield ``RecordedResults`` per frame from ``/dic/results``, in recorded order."""
        for channel, message in self.messages({rs.TOPIC_RESULTS}):
            if self.schema_name(channel) != rs.FRAME_RESULTS_SCHEMA:
                continue
            try:
                values = rs.decode_results(message.data)
            except rs.WireError as bad:
                raise CorruptRecording(f"{self.name} is corrupt: results message at log time {message.log_time} "
                                       f"({bad})") from None
            yield _recorded_results(values, message.publish_time)

    def _decoded(self, topic, schema, decode, what):
        """Yield ``decode(message bytes)`` for each message of ``topic`` with ``schema``; CorruptRecording if bad."""
        for channel, message in self.messages({topic}):
            if self.schema_name(channel) != schema:
                continue
            try:
                value = decode(message.data)
            except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
                raise CorruptRecording(f"{self.name} is corrupt: {what} message at log time {message.log_time} "
                                       f"({error if isinstance(error, rs.WireError) else type(error).__name__})"
                                       ) from None
            yield value

    def strain_fields(self):
        """Yield ``RecordedStrain`` per frame from ``/dic/strain`` (nothing for a recording without strain)."""
        yield from self._decoded(rs.TOPIC_STRAIN, rs.STRAIN_FIELD_SCHEMA,
                                 lambda data: _recorded_strain(rs.StrainField.FromString(data)), "strain")

    def extensometer_samples(self):
        """Yield ``RecordedExtensometerSample`` from ``/dic/extensometers``: per frame, one per extensometer."""
        for sample in self._decoded(rs.TOPIC_EXTENSOMETERS, rs.EXTENSOMETER_SAMPLE_SCHEMA,
                                    rs.ExtensometerSample.FromString, "extensometer"):
            yield RecordedExtensometerSample(
                frame_index=sample.frame_index, timestamp_ns=sample.timestamp_ns, name=sample.name,
                l0_px=sample.l0_px, l_px=sample.l_px, eng_strain=sample.eng_strain, true_strain=sample.true_strain,
                ok=sample.ok, status=sample.status)

    def extensometer_readings(self):
        """Yield ``(frame_index, timestamp_ns, dic.strain.extensometer.ExtensometerReadings)`` per recorded frame.

        The samples of one frame (consecutive messages with the same frame index) gathered
        in recorded order, as ``dic.strain.extensometer.read_extensometers`` returns them.
        """
        frame = []
        for sample in self.extensometer_samples():
            if frame and (sample.frame_index, sample.timestamp_ns) != (frame[0].frame_index, frame[0].timestamp_ns):
                yield frame[0].frame_index, frame[0].timestamp_ns, _readings(frame)
                frame = []
            frame.append(sample)
        if frame:
            yield frame[0].frame_index, frame[0].timestamp_ns, _readings(frame)

    def force_samples(self):
        """Yield ``RecordedForceSample`` from ``/machine/force``: one per tracked frame, none in older recordings."""
        for sample in self._decoded(rs.TOPIC_FORCE, rs.FORCE_SAMPLE_SCHEMA, rs.ForceSample.FromString, "force"):
            yield RecordedForceSample(frame_index=sample.frame_index, timestamp_ns=sample.timestamp_ns,
                                      force_N=sample.force_N, stress_MPa=sample.stress_MPa, ok=sample.ok,
                                      source=sample.source)

    def events(self):
        """List of ``RecordedEvent`` from ``/livedic/events``."""
        out = []
        for _, message in self.messages({rs.TOPIC_EVENTS}):
            try:
                event = rs.Event.FromString(message.data)
            except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
                raise CorruptRecording(f"{self.name} is corrupt: undecodable event at log time "
                                       f"{message.log_time} ({type(error).__name__})") from None
            out.append(RecordedEvent(event.timestamp_ns, event.kind, event.message, event.level))
        return out


def _data_records(f, opcode, length):
    """The records a data-section record at ``f``'s position holds: a chunk's contents, or the record itself."""
    if opcode == Opcode.HEADER:
        raise Damaged("a second header record")
    record = read_record(f, opcode, length)
    records = open_chunk(record) if opcode == Opcode.CHUNK else [record]
    if any(isinstance(record, Schema) and record.id == 0 for record in records):
        raise Damaged("schema id 0")
    return records


# ----------------------------------------------------------------------------- public readers

def read_session(path):
    """Session metadata of a recording, with non-string values decoded from JSON.

    Raises
    ------
    RecordingError
        Not a readable livedic recording, or ``NoSessionMetadata``.
    """
    return Recording(path).session()


def iter_results(path):
    """Yield ``RecordedResults`` per frame from ``/dic/results``, in recorded order."""
    yield from Recording(path).results()


def read_results(path):
    """List of ``RecordedResults``, one per recorded frame (see ``iter_results``)."""
    return list(iter_results(path))


def read_strain_fields(path):
    """List of ``RecordedStrain``, one per frame recorded with strain (empty for older recordings)."""
    return list(Recording(path).strain_fields())


def read_extensometer_samples(path):
    """List of ``RecordedExtensometerSample``: per frame, one per extensometer (empty without extensometers)."""
    return list(Recording(path).extensometer_samples())


def read_force_samples(path):
    """List of ``RecordedForceSample``, one per tracked frame (empty for recordings without force)."""
    return list(Recording(path).force_samples())


def read_events(path):
    """List of ``RecordedEvent`` from ``/livedic/events``."""
    return Recording(path).events()


def inspect_recording(path):
    """``RecordingInfo`` for any MCAP file: how it reads, what it holds, whether it is truncated.

    Reads every message (the recovery scan, or the index); raises ``RecordingError``
    only when the file is not MCAP or is corrupt.
    """
    recording = Recording(path, livedic_only=False)
    for _ in recording.messages():
        pass
    return recording.info


@contextmanager
def _as_source_errors():
    """``RecordingError`` raised inside becomes ``RecordingSourceError`` (same line, the original as cause)."""
    try:
        yield
    except RecordingSourceError:
        raise
    except RecordingError as error:
        raise RecordingSourceError(str(error)) from error


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
    writing to it. ``info`` (``RecordingInfo``) says after a pass whether the
    recording was truncated.

    Raises
    ------
    RecordingSourceError
        At construction, for a file that is not a livedic recording (one line); during
        iteration, at a corrupt record (frames before it have been delivered).
    """

    def __init__(self, path, *, realtime=False):
        with _as_source_errors():
            self._recording = Recording(path)
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
    def live(self):
        return self.realtime          # delivered at the frames' own pace, like a camera

    @property
    def settings(self):
        return {"kind": "mcap_replay", "path": self.path, "realtime": self.realtime,
                "recorded_source_uri": self.session.get("source_uri", ""),
                "recorded_start_time": self.session.get("start_time", "")}

    def close(self):
        self._closed = True

    def __iter__(self):
        with _as_source_errors():
            yield from self._frames()

    def _frames(self):
        recording = self._recording
        pending_info = None
        first = None
        for channel, message in recording.messages({rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO}):
            if self._closed:
                return
            schema = recording.schema_name(channel)
            if channel.topic == rs.TOPIC_FRAME_INFO:
                if schema == rs.FRAME_INFO_SCHEMA:
                    pending_info = self._frame_info(message)
                continue
            if schema != rs.RAW_IMAGE_SCHEMA:
                continue
            try:
                image, encoding, _, _ = rs.decode_raw_image(message.data)
            except rs.WireError as bad:
                raise CorruptRecording(f"{recording.name} is corrupt: image message at log time "
                                       f"{message.log_time} ({bad})") from None
            frame = self._frame(message, image, pending_info)
            pending_info = None
            if self.realtime:
                first = self._pace(first, frame.timestamp_ns)
            if self._closed:
                return
            yield frame

    def _frame_info(self, message):
        try:
            return rs.FrameInfo.FromString(message.data)
        except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
            raise CorruptRecording(f"{self._recording.name} is corrupt: undecodable frame info at log time "
                                   f"{message.log_time} ({type(error).__name__})") from None

    @staticmethod
    def _frame(message, image, info):
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


class FrameReader:
    """One frame's image at a time, by its (index, timestamp), from an indexed recording.

    For readers that need a few frames out of many, in any order (a worker of the parallel
    replay reading the frames it was given from a shared file system): only the image chunk
    whose time range holds the frame is read (the chunk index's message start and end times),
    and the last chunk read is kept, as consecutive frames share chunks when images are small.
    The frame is the ``/camera/image`` message logged at ``timestamp_ns`` (the one with MCAP
    sequence ``index`` where two share the time): ``McapSource``'s frame of that key.

    Raises
    ------
    RecordingError
        Not a readable livedic recording, or one without a sound index (truncated: ``recover``
        rewrites it indexed); ``image`` raises it for a frame the file does not hold or a
        damaged chunk.
    """

    def __init__(self, path):
        self._recording = Recording(path)
        recording = self._recording
        if recording.summary is None:
            raise RecordingError(f"{recording.name} has no index ({recording.summary_problem or 'truncated'}): its "
                                 f"frames cannot be read one by one; `recover` rewrites it indexed")
        self._image_ids = {cid for cid, channel in recording.channels.items()
                           if channel.topic == rs.TOPIC_IMAGE and recording.schema_name(channel) == rs.RAW_IMAGE_SCHEMA}
        self._chunk = (None, [])            # (offset, its records): the last chunk read
        self.chunks_read = 0

    @property
    def path(self):
        return self._recording.path

    def _candidates(self, timestamp_ns):
        for index in self._recording.summary.chunk_indexes:
            held = set(index.message_index_offsets)
            if held and not held & self._image_ids:
                continue
            if index.message_start_time <= timestamp_ns <= index.message_end_time:
                yield index

    def _records(self, index):
        offset = index.chunk_start_offset
        if self._chunk[0] != offset:
            with self._recording._open_file() as f:
                try:
                    records = open_chunk(read_record_at(f, offset, index.chunk_length, Opcode.CHUNK))
                except Damaged as bad:
                    raise self._recording._corrupt("a chunk", offset, bad) from None
            self._chunk = (offset, records)
            self.chunks_read += 1
        return self._chunk[1]

    def image(self, index, timestamp_ns):
        """The image (H, W) uint8/uint16 of frame ``index`` logged at ``timestamp_ns`` (read-only)."""
        timestamp_ns, index = int(timestamp_ns), int(index)
        for chunk in self._candidates(timestamp_ns):
            found = [record for record in self._records(chunk) if isinstance(record, Message)
                     and record.channel_id in self._image_ids and record.log_time == timestamp_ns]
            if len(found) > 1:
                found = [record for record in found if record.sequence == (index & 0xFFFFFFFF)] or found[:1]
            if found:
                try:
                    image, _, _, _ = rs.decode_raw_image(found[0].data)
                except rs.WireError as bad:
                    raise CorruptRecording(f"{self._recording.name} is corrupt: image message at log time "
                                           f"{timestamp_ns} ({bad})") from None
                return image
        raise RecordingError(f"{self._recording.name} holds no image of frame {index} at {timestamp_ns} ns")


# ----------------------------------------------------------------------------- recover

def recover(src, dst, *, overwrite=False, chunk_bytes=1 << 20, compression=None):
    """Rewrite a crashed or truncated livedic recording as a complete, indexed MCAP.

    Copies every schema, channel, metadata record and readable message of ``src``
    (in file order, with their log/publish times and sequences) into ``dst``, skipping
    corrupt chunks whose length is intact, and adds a ``livedic.recovery`` metadata
    record describing what was done. ``dst`` is written through an ``AtomicFile``
    (a temporary name beside it, fsynced and renamed when complete).

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
    OutputError
        ``dst``'s folder does not exist, or ``dst`` is a folder.
    """
    src_path, dst_path = os.fspath(src), os.fspath(dst)
    if os.path.realpath(src_path) == os.path.realpath(dst_path) or (
            os.path.exists(dst_path) and os.path.exists(src_path) and os.path.samefile(src_path, dst_path)):
        raise RecordingError(f"recover: destination {dst_path} is the source itself; choose another file")
    if os.path.exists(dst_path) and not overwrite:
        raise RecordingError(f"recover: {dst_path} already exists; pass overwrite=True to replace it")
    recording = Recording(src_path)
    recording.forget_index()                       # walk every record, whatever the index says
    counts = Counter()
    skipped = 0
    schema_map, channel_map, kinds = {}, {}, {}
    with AtomicFile(dst_path, binary=True) as out:
        writer = ChunkedWriter(out.handle, chunk_bytes=chunk_bytes, compression=compression,
                               library=library_name("recovered"))
        for record in recording.records(strict=False):
            if isinstance(record, Schema):
                if record.id not in schema_map:
                    schema_map[record.id] = writer.writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel):
                if record.id in channel_map or (record.schema_id and record.schema_id not in schema_map):
                    continue
                channel_map[record.id] = writer.writer.register_channel(
                    record.topic, record.message_encoding, schema_map.get(record.schema_id, 0), dict(record.metadata))
                kinds[record.id] = "image" if record.topic in (rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO) else "data"
            elif isinstance(record, Metadata):
                writer.writer.add_metadata(record.name, record.metadata)
            elif record.channel_id not in channel_map:
                skipped += 1
            else:
                writer.add(kinds[record.channel_id], channel_map[record.channel_id], record.log_time, record.data,
                           publish_time=record.publish_time, sequence=record.sequence)
                counts[recording.channels[record.channel_id].topic] += 1
        info = recording.info
        writer.writer.add_metadata(rs.RECOVERY_METADATA_NAME, {
            "source": os.path.abspath(src_path), "source_bytes": str(info.size_bytes),
            "valid_bytes": str(info.valid_bytes), "truncated": "true" if info.truncated else "false",
            "messages": str(sum(counts.values())), "corrupt_chunks": str(info.corrupt_chunks),
            "recovered_at": datetime.now(timezone.utc).isoformat()})
        writer.finish()
        if os.path.exists(dst_path) and not overwrite:
            raise RecordingError(f"recover: {dst_path} appeared while recovering; it was left as it is")
        out.commit(sync=True)
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
