"""Record a session to MCAP: raw frames, per-frame DIC results, strain, extensometers, force, events, metadata.

``Recorder(path, session)`` writes the livedic recording format (docs/guide/recording-format.md).
Image chunks (``/camera/*``) and data chunks (``/dic/*``, ``/machine/force``, ``/livedic/*``)
are kept apart, so an indexed reader fetches the results without reading any image. A chunk is
written when it holds ``chunk_bytes``, when its oldest message is ``flush_interval_s`` old
(checked on every write and by a background thread), and on ``flush()``/``close()``; the
background thread also calls ``os.fsync`` every ``fsync_interval_s``, off the writer lock.

Guarantees:

* every message whose write returned more than ``flush_interval_s`` + ~0.1 s before the
  process was killed is readable by ``acquire.recording.reader`` (counted in
  ``frames_durable`` / ``results_durable``); results never run ahead of their frames;
* on a full disk or any write error the recorder stops: ``error`` holds one line,
  ``on_error(message)`` is called once, later writes return False and are counted in the
  ``*_dropped`` counters, and nothing is raised into the caller's loop again; what was
  written stays readable (``acquire.recording.recover`` rewrites it indexed);
* writes are thread safe (one lock); arguments are validated before anything is written, a
  wrong call raises ``ValueError``/``TypeError`` at once.

Why this layout, crash safety, and what a write costs: docs/guide/recording-format.md
("Chunks, flushing and crash safety") and docs/guide/performance.md ("Recording").

Examples
--------
>>> import numpy as np, tempfile, os
>>> from livedic.acquire.base import Frame
>>> path = os.path.join(tempfile.mkdtemp(), "session.mcap")
>>> with Recorder(path, {"source_uri": "synthetic://"}) as rec:
...     rec.write_frame(Frame(0, 1_000, np.zeros((4, 6), np.uint8), "Mono8"))
...     rec.write_results(0, 1_000, [7], [2.0], [1.0], [0.1], [-0.2], [0.99], [True])
True
True
>>> rec.frames_written, rec.error
(1, None)
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable, Mapping
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Literal, cast

import numpy as np

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.recording.chunked_writer import ChunkedWriter, library_name, software_version
from livedic.acquire.recording.metadata import metadata_to_strings, to_json

if TYPE_CHECKING:
    import numpy.typing as npt
    from mcap.records import ChunkIndex

    from livedic.acquire.base import Frame
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.dic.strain.field import StrainField

__all__ = ["Recorder"]

log = logging.getLogger(__name__)

_U64 = 1 << 64
DEFAULT_CHUNK_BYTES = 4 << 20    # chosen by measurement: see acquire.recording.chunked_writer.ChunkedWriter
_RESULT_EXTRAS = rs.OPTIONAL_ARRAYS + rs.RESULT_SCALARS


class Recorder:
    """Write a livedic session to an MCAP file.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file to create. An existing file is never replaced unless
        ``overwrite=True`` (a recording of a test that cannot be repeated is precious).
    session_metadata : dict
        Source URI, camera settings, ROI, points, method and parameters ... Stored as
        the MCAP Metadata record ``livedic.session`` (string->string; non-string values
        as JSON) and as the first message on ``/livedic/session``. ``software_version``,
        ``start_time`` (ISO 8601, UTC) and ``start_time_ns`` are added when missing.
    chunk_bytes : int
        Write an image chunk, or the pending data, once it holds this many bytes
        (default 4 MiB; see the module notes).
    compression : None or "lz4"
        Chunk compression (zstd is accepted but too slow for live 1 MP frames).
    flush_interval_s : float
        Longest time a message waits in memory before it is written (default 0.25 s;
        up to ~0.1 s more when only the background thread is left to do it).
    fsync_interval_s : float or None
        Background ``os.fsync`` period (default 1 s); None disables it.
    on_error : callable, optional
        ``on_error(message)``, called once when recording stops on an error, from the
        thread that hit it (a writer, or the recorder's background thread), outside the
        recorder's lock.
    overwrite : bool
        Allow replacing an existing file.
    start_time_ns : int, optional
        Log time of the session message, in the frame clock. By default the session
        message is written just before the first message, with that message's log time
        (the first frame's timestamp), so that it shares the frames' clock whatever it
        is; the Metadata record is on disk from the start either way.

    Attributes
    ----------
    error : str or None
        Why recording stopped early (one line), None while all is well.
    frames_written, results_written, events_written : int
        Messages accepted.
    strain_written, extensometers_written, force_written : int
        ``write_strain`` / ``write_extensometers`` / ``write_force`` calls accepted (one per
        frame; the extensometers of a frame are one message each).
    frames_durable, results_durable : int
        Frames, results in chunks handed to the kernel (they survive a kill of this process).
    chunks_written : int
        Chunks written so far (mcap keeps an index entry per chunk in memory until ``close``).
    frames_dropped, results_dropped, events_dropped, strain_dropped, extensometers_dropped, force_dropped : int
        Writes refused after a stop or close.
    bytes_written : int
        File size handed to the kernel so far.

    Raises
    ------
    FileExistsError
        ``path`` exists and ``overwrite`` is False.
    OSError
        The file cannot be created or its first records cannot be written.
    """

    def __init__(self, path: str | os.PathLike[str], session_metadata: Mapping[str, Any], *,
                 chunk_bytes: int = DEFAULT_CHUNK_BYTES, compression: str | None = None,
                 flush_interval_s: float = 0.25, fsync_interval_s: float | None = 1.0,
                 on_error: Callable[[str], object] | None = None, overwrite: bool = False,
                 start_time_ns: int | None = None, stereo: bool = False) -> None:
        if not isinstance(session_metadata, Mapping):
            raise TypeError(f"session_metadata must be a dict, got {type(session_metadata).__name__}")
        if not isinstance(chunk_bytes, (int, np.integer)) or chunk_bytes <= 0:
            raise ValueError(f"chunk_bytes must be a positive integer, got {chunk_bytes!r}")
        if compression not in (None, "lz4", "zstd"):
            raise ValueError(f"compression must be None or 'lz4', got {compression!r}")
        if not flush_interval_s or flush_interval_s <= 0:
            raise ValueError(f"flush_interval_s must be > 0, got {flush_interval_s!r}")
        if fsync_interval_s is not None and fsync_interval_s <= 0:
            raise ValueError(f"fsync_interval_s must be > 0 or None, got {fsync_interval_s!r}")
        self.path = os.fspath(path)
        self.stereo = bool(stereo)
        self.error: str | None = None
        self.frames_written = self.results_written = self.events_written = 0
        self.right_frames_written = self.right_frames_dropped = 0
        self.frames_dropped = self.results_dropped = self.events_dropped = 0
        self.strain_written = self.extensometers_written = self.force_written = 0
        self.strain_dropped = self.extensometers_dropped = self.force_dropped = 0
        self.bytes_written = 0
        self._on_error = on_error
        self._flush_interval_s = float(flush_interval_s)
        self._fsync_interval_s = fsync_interval_s
        self._lock = threading.RLock()
        self._closed = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._sync_fd: int | None = None
        self._event_count = 0
        self._notify_pending = False
        wall_ns = time.time_ns()
        self._start_ns = None if start_time_ns is None else _log_time(start_time_ns, "start_time_ns")
        self._start_mono = time.monotonic_ns()
        self._session_payload: bytes | None = None   # until written: the session message waits for the clock
        self._last_frame: tuple[int, int] | None = None   # (timestamp_ns, monotonic_ns) of the last frame
        self._chunks_seen = 0                # chunks_written when bytes_written was last updated

        metadata = dict(session_metadata)
        metadata.setdefault("software_version", software_version())
        metadata.setdefault("start_time", datetime.now(timezone.utc).isoformat())
        metadata.setdefault("start_time_ns", wall_ns if self._start_ns is None else self._start_ns)
        metadata[rs.FORMAT_KEY] = rs.FORMAT_VERSION
        strings = metadata_to_strings(metadata)

        try:
            self._file = open(self.path, "wb" if overwrite else "xb")
        except FileExistsError:
            raise FileExistsError(f"{self.path} exists: choose a new name or pass overwrite=True") from None
        self._start_file(strings, int(chunk_bytes), compression, fsync_interval_s)
        if fsync_interval_s is not None:
            self._sync_fd = os.dup(self._file.fileno())
        self._last_sync = time.monotonic()
        self._synced_bytes = self.bytes_written
        self._thread = threading.Thread(target=self._background, name="livedic-recorder", daemon=True)
        self._thread.start()

    def _start_file(self, strings: dict[str, str], chunk_bytes: int, compression: str | None,
                    fsync_interval_s: float | None) -> None:
        """The chunk writer, every channel and the session metadata, on disk; the file removed if any fails."""
        try:
            self._cw = ChunkedWriter(self._file, chunk_bytes=chunk_bytes, compression=compression,
                                      library=library_name(), flush_interval_s=self._flush_interval_s)
            channel = self._channel
            self._view_channels = {view: (channel(image, rs.RAW_IMAGE_SCHEMA), channel(info, rs.FRAME_INFO_SCHEMA))
                                   for view, (image, info) in rs.VIEW_TOPICS.items()
                                   if view == "left" or self.stereo}
            self._ch_results = channel(rs.TOPIC_RESULTS, rs.FRAME_RESULTS_SCHEMA)
            self._ch_events = channel(rs.TOPIC_EVENTS, rs.EVENT_SCHEMA)
            self._ch_strain = channel(rs.TOPIC_STRAIN, rs.STRAIN_FIELD_SCHEMA)
            self._ch_extensometers = channel(rs.TOPIC_EXTENSOMETERS, rs.EXTENSOMETER_SAMPLE_SCHEMA)
            self._ch_force = channel(rs.TOPIC_FORCE, rs.FORCE_SAMPLE_SCHEMA)
            self._ch_session = channel(rs.TOPIC_SESSION, rs.SESSION_SCHEMA)
            self._cw.writer.add_metadata(rs.METADATA_NAME, strings)
            self._session_payload = rs.Session(metadata=strings).SerializeToString()
            if self._start_ns is not None:
                self._write_session(self._start_ns)
            self._cw.flush()                     # header + metadata record reach the kernel now
            if fsync_interval_s is not None:
                os.fsync(self._file.fileno())
            self.bytes_written = self._file.tell()
            self._chunks_seen = self._cw.chunks_written
        except BaseException:
            self._file.close()
            try:
                os.remove(self.path)
            except OSError:
                pass
            raise

    def _channel(self, topic: str, schema_name: str) -> int:
        return self._cw.register(topic, schema_name, rs.schema_data(schema_name))

    # ------------------------------------------------------------------ public API

    @property
    def frames_durable(self) -> int:
        return self._cw.durable_counts["frame"]

    @property
    def results_durable(self) -> int:
        return self._cw.durable_counts["results"]

    @property
    def chunks_written(self) -> int:
        return self._cw.chunks_written

    def chunk_indexes(self) -> list[ChunkIndex]:
        """The chunk indexes held in memory for the file's summary (a diagnostic), or None."""
        return self._cw.chunk_indexes()

    @property
    def closed(self) -> bool:
        return self._closed

    def write_frame(self, frame: Frame, view: Literal["left", "right"] = "left") -> bool:
        """Record ``frame`` (an ``acquire.base.Frame``) on ``/camera/image`` (``view`` "right": a stereo
        recorder's ``/camera/right/image``).

        The image becomes a ``foxglove.RawImage`` (mono8 for uint8, mono16 for uint16)
        with log time ``frame.timestamp_ns`` and MCAP sequence ``frame.index mod 2**32``.
        A ``/camera/frame_info`` message goes with it when the frame has metadata, a pixel
        format other than Mono8/Mono16 (e.g. Mono12), or an index >= 2**32. The right view's
        frames count in ``right_frames_written`` / ``right_frames_dropped``, not in ``frames_*``.

        Returns
        -------
        bool
            True if accepted (counted in ``*_written``), False if dropped (counted in
            ``*_dropped``) because recording has stopped, or stopped on this write.
        """
        if view not in self._view_channels:
            raise ValueError(f"view must be one of {sorted(self._view_channels)} for this recorder, got {view!r}"
                             + ("" if self.stereo else " (a right view needs Recorder(..., stereo=True))"))
        if self._refused("frames" if view == "left" else "right_frames"):
            return False
        channel_image, channel_info = self._view_channels[view]
        image = frame.image
        encoding = wire.image_encoding(image)
        timestamp_ns = _log_time(frame.timestamp_ns, "frame.timestamp_ns")
        index = int(frame.index)
        if index < 0:
            raise ValueError(f"frame.index must be >= 0, got {index}")
        payload = wire.raw_image_parts(image, timestamp_ns)   # the pixels are copied once, into the chunk
        canonical = rs.DEFAULT_PIXEL_FORMAT[np.dtype("u1") if encoding == "mono8" else np.dtype("u2")]
        info = None
        if frame.metadata or frame.pixel_format != canonical or index >= 1 << 32:
            info = rs.FrameInfo(frame_index=index, timestamp_ns=timestamp_ns, pixel_format=str(frame.pixel_format),
                                metadata_json=to_json(dict(frame.metadata)) if frame.metadata else "")
            info = info.SerializeToString()

        def add() -> None:
            now = time.time_ns()
            sequence = index & 0xFFFFFFFF
            if info is not None:
                self._cw.add("image", channel_info, timestamp_ns, info, publish_time=now, sequence=sequence)
            self._cw.add("image", channel_image, timestamp_ns, payload, publish_time=now,
                         sequence=sequence, count_as="frame" if view == "left" else "right_frame")
            if view == "left":
                self._last_frame = (timestamp_ns, time.monotonic_ns())

        return self._write("frames" if view == "left" else "right_frames", "write_frame", timestamp_ns, add)

    def write_results(self, frame_index: int, timestamp_ns: int, point_ids: npt.ArrayLike, x: npt.ArrayLike,
                      y: npt.ArrayLike, u: npt.ArrayLike, v: npt.ArrayLike, zncc: npt.ArrayLike, ok: npt.ArrayLike,
                      **extra: Any) -> bool:
        """Record one frame's DIC results on ``/dic/results`` (``livedic.FrameResults``).

        Parameters
        ----------
        frame_index : int
        timestamp_ns : int
            The frame's timestamp; also the message log time.
        point_ids : array_like of int, shape (N,)
        x, y : array_like of float, shape (N,)
            Point positions in the reference image (px; x along columns, y along rows).
        u, v : array_like of float, shape (N,)
            Displacement along x and y (px).
        zncc : array_like of float, shape (N,)
        ok : array_like of bool, shape (N,)
        **extra
            Optional arrays ``ux, uy, vx, vy`` (float), ``status`` (int), ``iterations``
            (int), each shape (N,), and scalars ``method`` (str), ``processing_ns``,
            ``latency_ns``, ``reference_frame_index``, ``dropped_frames`` (int).

        Returns
        -------
        bool
            True if accepted (counted in ``*_written``), False if dropped (counted in
            ``*_dropped``) because recording has stopped, or stopped on this write.

        Raises
        ------
        TypeError
            Unknown keyword.
        ValueError
            Arrays of different lengths or not 1-D, ids or counts out of range.
        """
        if self._refused("results"):
            return False
        unknown = sorted(set(extra) - set(_RESULT_EXTRAS))
        if unknown:
            raise TypeError(f"write_results() got unexpected keyword(s) {', '.join(unknown)}; "
                            f"known: {', '.join(_RESULT_EXTRAS)}")
        timestamp_ns = _log_time(timestamp_ns, "timestamp_ns")
        frame_index = int(frame_index)
        if not 0 <= frame_index < _U64:
            raise ValueError(f"frame_index must be >= 0, got {frame_index}")
        values: dict[str, Any] = {"frame_index": frame_index, "timestamp_ns": timestamp_ns}
        arrays = {"point_id": point_ids, "x": x, "y": y, "u": u, "v": v, "zncc": zncc, "ok": ok}
        arrays.update({name: extra[name] for name in rs.OPTIONAL_ARRAYS if extra.get(name) is not None})
        length = None
        for name, value in arrays.items():
            array = _as_1d(value, "point_ids" if name == "point_id" else name)
            if length is None:
                length = array.size
            elif array.size != length:
                raise ValueError(f"write_results: {name} has {array.size} entries but point_ids has {length}")
            values[name] = _convert(array, name)
        for name in rs.RESULT_SCALARS:
            given = extra.get(name)
            if given is None:
                continue
            if name == "method":
                values[name] = str(given)
                continue
            number = int(given)
            if name in ("reference_frame_index", "dropped_frames") and number < 0:
                raise ValueError(f"write_results: {name} must be >= 0, got {number}")
            limit = 1 << 32 if name == "dropped_frames" else 1 << 63
            if not -limit <= number < limit:
                raise ValueError(f"write_results: {name}={number} is out of range")
            values[name] = number
        payload = wire.encode_results(values)
        return self._write("results", "write_results", timestamp_ns, lambda: self._cw.add(
            "data", self._ch_results, timestamp_ns, payload, publish_time=time.time_ns(),
            sequence=frame_index & 0xFFFFFFFF, count_as="results"))

    def write_strain(self, frame_index: int, timestamp_ns: int, strain_field: StrainField, *,
                     window: int | None = None) -> bool:
        """Record one frame's strain field on ``/dic/strain`` (``livedic.StrainField``).

        Parameters
        ----------
        frame_index : int
        timestamp_ns : int
            The frame's timestamp; also the message log time.
        strain_field : dic.strain.StrainField
            Its ``exx, eyy, exy, e1, e2`` (float) and ``status`` (``StrainStatus`` codes), shape
            (N,), one entry per point of the frame's ``write_results`` call, in the same
            order: point ids are 0..N-1 as there; ``measure`` and ``vsg_px`` are recorded too.
        window : int, optional
            Points a side of the strain window (``StrainWindow.window``); taken from
            ``strain_field.window`` when it has one, else 0 ("not given").

        Returns
        -------
        bool
            True if accepted (counted in ``strain_written``), False if dropped (counted in
            ``strain_dropped``) because recording has stopped, or stopped on this write.

        Raises
        ------
        ValueError
            Arrays of different lengths or not 1-D, a status out of the 32-bit range, a bad window.
        """
        if self._refused("strain"):
            return False
        timestamp_ns = _log_time(timestamp_ns, "timestamp_ns")
        frame_index = _frame_index(frame_index, "write_strain")
        window = window if window is not None else getattr(strain_field, "window", None)
        window = 0 if window is None else int(window)
        if not 0 <= window < 1 << 32:
            raise ValueError(f"write_strain: window must be a number of points >= 0, got {window}")
        values: dict[str, Any] = {"frame_index": frame_index, "timestamp_ns": timestamp_ns, "window": window,
                                  "measure": str(strain_field.measure), "vsg_px": float(strain_field.vsg_px)}
        length = None
        for name in rs.STRAIN_ARRAYS[1:]:
            array = _as_1d(getattr(strain_field, name), name, "write_strain")
            if length is None:
                length = array.size
            elif array.size != length:
                raise ValueError(f"write_strain: {name} has {array.size} entries but exx has {length}")
            values[name] = _convert(array, name, "write_strain", rs.STRAIN_DTYPES)
        values["point_id"] = np.arange(length or 0, dtype=np.uint32)      # length: set by the loop
        payload = wire.encode_strain(values)
        return self._write("strain", "write_strain", timestamp_ns, lambda: self._cw.add(
            "data", self._ch_strain, timestamp_ns, payload, publish_time=time.time_ns(),
            sequence=frame_index & 0xFFFFFFFF, count_as="strain"))

    def write_extensometers(self, frame_index: int, timestamp_ns: int, readings: ExtensometerReadings) -> bool:
        """Record one frame's extensometer readings on ``/dic/extensometers``: one message each.

        Parameters
        ----------
        frame_index : int
        timestamp_ns : int
            The frame's timestamp; also the messages' log time.
        readings : dic.strain.extensometer.ExtensometerReadings
            ``names`` and, per extensometer, ``l0_px``, ``length_px``, ``eng_strain``,
            ``true_strain`` and ``status`` (``ExtensometerStatus`` codes; ok where 0). A
            ``livedic.ExtensometerSample`` is written for each, in that order; none when
            there are no extensometers.

        Returns
        -------
        bool
            True if accepted (counted in ``extensometers_written``, once per call), False if
            dropped (counted in ``extensometers_dropped``) because recording has stopped.

        Raises
        ------
        ValueError
            Arrays whose lengths differ from the number of names, a status out of the 32-bit range.
        """
        if self._refused("extensometers"):
            return False
        timestamp_ns = _log_time(timestamp_ns, "timestamp_ns")
        frame_index = _frame_index(frame_index, "write_extensometers")
        names = [str(name) for name in readings.names]
        columns = {}
        for name in ("l0_px", "length_px", "eng_strain", "true_strain", "status"):
            array = _as_1d(getattr(readings, name), name, "write_extensometers")
            if array.size != len(names):
                raise ValueError(f"write_extensometers: {name} has {array.size} entries for {len(names)} names")
            columns[name] = _convert(array, name, "write_extensometers", {"status": np.dtype(np.int32)})
        in_space = {}
        if readings.l0_mm is not None:         # a stereo session's lengths in space
            for name, field_name in (("l0_mm", "l0_mm"), ("length_mm", "l_mm")):
                array = _as_1d(getattr(readings, name), name, "write_extensometers")
                if array.size != len(names):
                    raise ValueError(f"write_extensometers: {name} has {array.size} entries for {len(names)} names")
                in_space[field_name] = array.astype(np.float64, copy=False)
        ok = columns["status"] == 0
        payloads = [rs.ExtensometerSample(
            frame_index=frame_index, timestamp_ns=timestamp_ns, name=name, l0_px=columns["l0_px"][i],
            l_px=columns["length_px"][i], eng_strain=columns["eng_strain"][i],
            true_strain=columns["true_strain"][i], ok=bool(ok[i]), status=int(columns["status"][i]),
            **{field_name: float(values[i]) for field_name, values in in_space.items()}
        ).SerializeToString() for i, name in enumerate(names)]

        def add() -> None:
            publish_time = time.time_ns()
            for payload in payloads:
                self._cw.add("data", self._ch_extensometers, timestamp_ns, payload, publish_time=publish_time,
                             sequence=frame_index & 0xFFFFFFFF, count_as="extensometer")

        return self._write("extensometers", "write_extensometers", timestamp_ns, add)

    def write_force(self, frame_index: int, timestamp_ns: int, force_N: float | None, stress_MPa: float | None, *,
                    source: str = "") -> bool:
        """Record the machine's force on one tracked frame on ``/machine/force`` (``livedic.ForceSample``).

        Parameters
        ----------
        frame_index : int
        timestamp_ns : int
            The frame's timestamp; also the message log time.
        force_N : float
            The force at the frame's time (N); NaN (or None) when the load had no value for
            this frame (a lost or late stream): ``ok`` is recorded False then.
        stress_MPa : float
            Engineering stress ``force_N / A0`` (MPa); NaN (or None) without a cross-section.
        source : str
            The load URI the force came from (``--load``), recorded in every message.

        Returns
        -------
        bool
            True if accepted (counted in ``force_written``), False if dropped (counted in
            ``force_dropped``) because recording has stopped, or stopped on this write.

        Raises
        ------
        ValueError
            A force or stress that is not a number (NaN and None are accepted).
        """
        if self._refused("force"):
            return False
        timestamp_ns = _log_time(timestamp_ns, "timestamp_ns")
        frame_index = _frame_index(frame_index, "write_force")
        force_N = _scalar(force_N, "force_N", "write_force")
        stress_MPa = _scalar(stress_MPa, "stress_MPa", "write_force")
        payload = rs.ForceSample(frame_index=frame_index, timestamp_ns=timestamp_ns, force_N=force_N,
                                 stress_MPa=stress_MPa, ok=bool(np.isfinite(force_N)),
                                 source=str(source)).SerializeToString()
        return self._write("force", "write_force", timestamp_ns, lambda: self._cw.add(
            "data", self._ch_force, timestamp_ns, payload, publish_time=time.time_ns(),
            sequence=frame_index & 0xFFFFFFFF, count_as="force"))

    def write_event(self, kind: str, message: str, *, level: str = "info", timestamp_ns: int | None = None) -> bool:
        """Record a note on ``/livedic/events`` (``livedic.Event``).

        Parameters
        ----------
        kind : str
            Short machine-readable kind: "drop", "camera_lost", "recording_stopped", "note" ...
        message : str
            One line for people.
        level : {"info", "warning", "error"}
        timestamp_ns : int, optional
            In the frame clock. By default: the last frame's timestamp plus the host time
            elapsed since it was written (``start_time_ns`` plus elapsed before any frame).

        Returns
        -------
        bool
            True if accepted (counted in ``*_written``), False if dropped (counted in
            ``*_dropped``) because recording has stopped, or stopped on this write.
        """
        if self._refused("events"):
            return False
        if level not in rs.EVENT_LEVELS:
            raise ValueError(f"level must be one of {', '.join(rs.EVENT_LEVELS)}, got {level!r}")
        if timestamp_ns is None:
            last_frame = self._last_frame      # one tuple, replaced whole: safe to read without the lock
            if last_frame is not None:
                timestamp_ns = last_frame[0] + (time.monotonic_ns() - last_frame[1])
            elif self._start_ns is not None:
                timestamp_ns = self._start_ns + (time.monotonic_ns() - self._start_mono)
            else:
                timestamp_ns = time.time_ns()
        timestamp_ns = _log_time(timestamp_ns, "timestamp_ns")
        payload = rs.Event(timestamp_ns=timestamp_ns, kind=str(kind), message=str(message),
                           level=level).SerializeToString()

        def add() -> None:
            self._event_count += 1
            self._cw.add("data", self._ch_events, timestamp_ns, payload, publish_time=time.time_ns(),
                         sequence=self._event_count & 0xFFFFFFFF, count_as="event")

        return self._write("events", "write_event", timestamp_ns, add)

    def flush(self) -> bool:
        """Write the open image chunk and the pending data, and fsync now. Never raises; False if stopped."""
        written = True
        with self._lock:
            if self.error is not None or self._closed:
                return False
            try:
                self._cw.flush()
                self.bytes_written = self._file.tell()
                os.fsync(self._file.fileno())
            except Exception as error:  # noqa: BLE001
                self._fail(error, "flush")
                written = False
        self._notify()
        return written

    def close(self) -> None:
        """Finish the file (last chunk, summary, index, footer), fsync and close it.

        Idempotent and never raises: a failure on the way sets ``error`` (and calls
        ``on_error``) and leaves a file the recovering reader can read.
        """
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        with self._lock:
            if self.error is None:
                try:
                    self._write_session(time.time_ns())
                    self._cw.finish()
                    self.bytes_written = self._file.tell()
                    if self._fsync_interval_s is not None:
                        os.fsync(self._file.fileno())
                except Exception as error:  # noqa: BLE001
                    self._fail(error, "close")
            self._close_file()
        self._notify()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> Literal[False]:
        self.close()
        return False

    def __repr__(self) -> str:
        state = "closed" if self._closed else ("stopped" if self.error else "recording")
        return (f"Recorder({self.path!r}, {state}, frames={self.frames_written}, "
                f"bytes={self.bytes_written})")

    # ------------------------------------------------------------------ internals

    def _refused(self, what: str) -> bool:
        """True (and counted in ``{what}_dropped``) once recording has stopped: skip the encoding."""
        if self.error is None and not self._closed:
            return False
        with self._lock:
            setattr(self, f"{what}_dropped", getattr(self, f"{what}_dropped") + 1)
        return True

    def _write(self, what: str, during: str, timestamp_ns: int, add: Callable[[], None]) -> bool:
        """Run ``add()`` under the lock unless recording has stopped; count it in ``{what}_written``
        or ``{what}_dropped``; a failure stops recording (never raised). Returns True if written."""
        written = False
        with self._lock:
            if self.error is None and not self._closed:
                try:
                    self._write_session(timestamp_ns)
                    add()
                    written = True
                    self._after_write()
                except Exception as error:  # noqa: BLE001 - any write failure stops recording, never the loop
                    self._fail(error, during)
            counter = f"{what}_written" if written else f"{what}_dropped"
            setattr(self, counter, getattr(self, counter) + 1)
        self._notify()
        return written

    def _write_session(self, log_time: int) -> None:
        """The ``/livedic/session`` message, once, before any other message (frame clock)."""
        if self._session_payload is not None:
            payload, self._session_payload = self._session_payload, None
            self._cw.add("data", self._ch_session, log_time, payload, publish_time=time.time_ns())
            self._cw.write_data()            # its own chunk, first in the file: a cut file still has it

    def _after_write(self) -> None:
        self._cw.flush_due()
        if self._cw.chunks_written != self._chunks_seen:
            self._chunks_seen = self._cw.chunks_written
            self.bytes_written = self._file.tell()

    def _background(self) -> None:
        """Close chunks that have waited too long and fsync periodically (owns ``_sync_fd``)."""
        try:
            self._background_loop()
            self._notify()
        finally:
            if self._sync_fd is not None:
                try:
                    os.close(self._sync_fd)
                except OSError:
                    pass
                self._sync_fd = None

    def _background_loop(self) -> None:
        period = min(self._flush_interval_s / 2, 0.1)
        while not self._stop.wait(period):
            with self._lock:
                if self.error is not None or self._closed:
                    return
                try:
                    if self._cw.flush_due():
                        self._chunks_seen = self._cw.chunks_written
                        self.bytes_written = self._file.tell()
                except Exception as error:  # noqa: BLE001
                    self._fail(error, "background flush")
                    return
                target = self.bytes_written
            if (self._sync_fd is not None and target > self._synced_bytes
                    and time.monotonic() - self._last_sync >= cast(float, self._fsync_interval_s)):
                try:
                    os.fsync(self._sync_fd)  # outside the lock: writers never wait for the disk
                except OSError as error:
                    with self._lock:
                        self._fail(error, "fsync")
                    return
                self._synced_bytes = target
                self._last_sync = time.monotonic()

    def _fail(self, error: BaseException, during: str) -> None:
        if self.error is not None:
            return
        if isinstance(error, OSError) and error.strerror:
            reason = error.strerror
        else:
            reason = f"{type(error).__name__}: {error}" if str(error) else type(error).__name__
        self.error = (f"recording stopped: cannot write {self.path} ({reason}) in {during}; "
                      f"the {self.frames_durable} frames before it are safe, later writes are dropped")
        # Said once: by the caller's on_error when there is one, else by the log.
        (log.debug if self._on_error is not None else log.error)(self.error)
        self._close_file()
        self._notify_pending = self._on_error is not None

    def _notify(self) -> None:
        """Call ``on_error`` once, outside the lock (so the callback may call ``close``)."""
        with self._lock:
            pending, self._notify_pending = self._notify_pending, False
        if pending and self._on_error is not None and self.error is not None:    # pending implies both
            try:
                self._on_error(self.error)
            except Exception:  # noqa: BLE001 - a broken callback must not break the caller's loop
                log.exception("Recorder on_error callback failed")

    def _close_file(self) -> None:
        try:
            self._file.close()
        except Exception:  # noqa: BLE001 - buffered bytes that cannot be written are lost anyway
            pass


def _log_time(value: int, name: str) -> int:
    value = int(value)
    if not 0 <= value < _U64:
        raise ValueError(f"{name} must be in [0, 2**64) ns for MCAP, got {value}")
    return value


def _frame_index(value: int, during: str) -> int:
    value = int(value)
    if not 0 <= value < _U64:
        raise ValueError(f"{during}: frame_index must be >= 0, got {value}")
    return value


def _scalar(value: float | None, name: str, during: str) -> float:
    """``value`` as a float, NaN for None; ValueError when it is not a number."""
    if value is None:
        return float("nan")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{during}: {name} must be a number or NaN, got {value!r}") from None


def _as_1d(value: npt.ArrayLike, name: str, during: str = "write_results") -> np.ndarray:
    array = np.asarray(value)
    if array.ndim != 1:
        raise ValueError(f"{during}: {name} must be 1-D, got shape {array.shape}")
    return array


def _convert(array: np.ndarray, name: str, during: str = "write_results",
             dtypes: Mapping[str, np.dtype] = wire.RESULT_DTYPES) -> np.ndarray:
    dtype = dtypes.get(name, np.dtype(np.float64))
    name = "point_ids" if name == "point_id" else name          # the argument's name, for messages
    if dtype == np.uint32 and array.dtype != np.uint32:
        if array.size and (array.dtype.kind not in "iub" or array.min() < 0 or array.max() >= 1 << 32):
            raise ValueError(f"{during}: {name} must be integers in [0, 2**32)")
    elif dtype == np.int32 and array.dtype != np.int32:
        if array.size and (array.dtype.kind not in "iub" or array.min() < -(1 << 31) or array.max() >= 1 << 31):
            raise ValueError(f"{during}: {name} must be 32-bit integers")
    return array.astype(dtype, copy=False)
