"""Frames replayed from a livedic recording: ``McapSource`` (every ``/camera/image`` frame, in order, a
``FrameSource``) and ``FrameReader`` (one frame at a time, by its key, from an indexed file).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Literal, cast

import numpy as np
from mcap.opcode import Opcode
from mcap.records import Chunk, ChunkIndex, McapRecord, Message

from livedic.acquire.base import Frame, FrameSource
from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.recording.container import Damaged, open_chunk, read_record_at
from livedic.acquire.recording.errors import CorruptRecording, RecordingError, RecordingSourceError
from livedic.acquire.recording.metadata import metadata_from_strings
from livedic.acquire.recording.reader import Recording
from livedic.acquire.recording.records import RecordingInfo
from livedic.acquire.stereo import PairingCounts, pair_by_index

__all__ = ["FrameReader", "McapPairs", "McapSource"]


@contextmanager
def _as_source_errors() -> Iterator[None]:
    """``RecordingError`` raised inside becomes ``RecordingSourceError`` (same line, the original as cause)."""
    try:
        yield
    except RecordingSourceError:
        raise
    except RecordingError as error:
        raise RecordingSourceError(str(error)) from error


class McapSource(FrameSource):
    """Frames from a livedic recording's ``/camera/image`` channel (a stereo recording's right view:
    ``/camera/right/image``).

    Parameters
    ----------
    path : str or os.PathLike
    realtime : bool
        Sleep so that frames come at the recorded pace (log time deltas); otherwise
        as fast as possible.
    view : {"left", "right"}
        Which camera of a stereo recording (a 2D recording has the left only).

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

    def __init__(self, path: str | os.PathLike[str], *, realtime: bool = False,
                 view: Literal["left", "right"] = "left") -> None:
        if view not in rs.VIEW_TOPICS:
            raise ValueError(f"view must be one of {', '.join(rs.VIEWS)}, got {view!r}")
        with _as_source_errors():
            self._recording = Recording(path)
        self.path = self._recording.path
        self.view = view
        self._topics = rs.VIEW_TOPICS[view]
        if view != "left" and not any(channel.topic == self._topics[0]
                                      for channel in self._recording.channels.values()):
            raise RecordingSourceError(f"{self._recording.name} has no {view} view ({self._topics[0]}): "
                                       "it is not a stereo recording")
        self.uri = f"mcap:{self.path}" + ("" if view == "left" else f"?view={view}")
        self.realtime = bool(realtime)
        self._closed = False
        try:
            strings = self._recording.session_strings()
        except RecordingError:
            strings = None
        self.session = metadata_from_strings(strings) if strings else {}

    @property
    def info(self) -> RecordingInfo:
        """``RecordingInfo`` of the last (or current) pass over the file."""
        return self._recording.info

    @property
    def live(self) -> bool:
        return self.realtime          # delivered at the frames' own pace, like a camera

    @property
    def settings(self) -> dict[str, Any]:
        return {"kind": "mcap_replay", "path": self.path, "realtime": self.realtime,
                "recorded_source_uri": self.session.get("source_uri", ""),
                "recorded_start_time": self.session.get("start_time", "")}

    def close(self) -> None:
        self._closed = True

    def __iter__(self) -> Iterator[Frame]:
        with _as_source_errors():
            yield from self._frames()

    def _frames(self) -> Iterator[Frame]:
        recording = self._recording
        pending_info = None
        first: tuple[float, int] | None = None
        image_topic, info_topic = self._topics
        for channel, message in recording.messages({image_topic, info_topic}):
            if self._closed:
                return
            schema = recording.schema_name(channel)
            if channel.topic == info_topic:
                if schema == rs.FRAME_INFO_SCHEMA:
                    pending_info = self._frame_info(message)
                continue
            if schema != rs.RAW_IMAGE_SCHEMA:
                continue
            try:
                image, encoding, _, _ = wire.decode_raw_image(message.data)
            except wire.WireError as bad:
                raise CorruptRecording(f"{recording.name} is corrupt: image message at log time "
                                       f"{message.log_time} ({bad})") from None
            frame = self._frame(message, image, pending_info)
            pending_info = None
            if self.realtime:
                first = self._pace(first, frame.timestamp_ns)
            if self._closed:
                return
            yield frame

    def _frame_info(self, message: Message) -> Any:
        try:
            return rs.FrameInfo.FromString(message.data)
        except Exception as error:  # noqa: BLE001 - protobuf raises DecodeError and friends
            raise CorruptRecording(f"{self._recording.name} is corrupt: undecodable frame info at log time "
                                   f"{message.log_time} ({type(error).__name__})") from None

    @staticmethod
    def _frame(message: Message, image: np.ndarray, info: Any) -> Frame:
        index = message.sequence
        pixel_format = "Mono8" if image.dtype == np.uint8 else "Mono16"
        metadata: dict[str, Any] = {}
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

    def _pace(self, first: tuple[float, int] | None, timestamp_ns: int) -> tuple[float, int]:
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


class McapPairs(FrameSource):
    """A stereo recording's pairs: each ``/camera/image`` frame with the ``/camera/right/image`` frame of the same
    index in ``Frame.right`` (``acquire.stereo.pair_by_index``), as ``PairedFrames`` delivered them live.

    A frame whose index the other view lacks is dropped and counted (``counts``, a ``PairingCounts``), never paired
    with another. ``stereo`` marks it, as ``PairedFrames``.

    Raises
    ------
    RecordingSourceError
        At construction: not a livedic recording, or not a stereo one (no right view); during iteration, at a
        corrupt record.
    """

    stereo = True

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.right = McapSource(path, view="right")
        self.left = McapSource(path)
        self.path, self.uri = self.left.path, self.left.uri
        self.counts = PairingCounts()

    @property
    def info(self) -> RecordingInfo:
        """The left view's ``RecordingInfo`` (one file: truncated for both)."""
        return self.left.info

    @property
    def settings(self) -> dict[str, Any]:
        return {**self.left.settings, "source": "stereo", "pairing": self.counts.as_dict()}

    def __iter__(self) -> Iterator[Frame]:
        return pair_by_index(self.left, self.right, self.counts)

    def close(self) -> None:
        self.left.close()
        self.right.close()


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

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self._recording = Recording(path)
        recording = self._recording
        if recording.summary is None:
            raise RecordingError(f"{recording.name} has no index ({recording.summary_problem or 'truncated'}): its "
                                 f"frames cannot be read one by one; `recover` rewrites it indexed")
        self._image_ids = {cid for cid, channel in recording.channels.items()
                           if channel.topic == rs.TOPIC_IMAGE and recording.schema_name(channel) == rs.RAW_IMAGE_SCHEMA}
        self._chunk: tuple[int | None, list[McapRecord]] = (None, [])   # (offset, its records): the last chunk read
        self.chunks_read = 0

    @property
    def path(self) -> str:
        return self._recording.path

    def _candidates(self, timestamp_ns: int) -> Iterator[ChunkIndex]:
        summary = self._recording.summary
        if summary is None:              # refused at construction
            return
        for index in summary.chunk_indexes:
            held = set(index.message_index_offsets)
            if held and not held & self._image_ids:
                continue
            if index.message_start_time <= timestamp_ns <= index.message_end_time:
                yield index

    def _records(self, index: ChunkIndex) -> list[McapRecord]:
        offset = index.chunk_start_offset
        if self._chunk[0] != offset:
            with self._recording._open_file() as f:
                try:
                    records = open_chunk(cast(Chunk, read_record_at(f, offset, index.chunk_length, Opcode.CHUNK)))
                except Damaged as bad:
                    raise self._recording._corrupt("a chunk", offset, bad) from None
            self._chunk = (offset, records)
            self.chunks_read += 1
        return self._chunk[1]

    def image(self, index: int, timestamp_ns: int) -> np.ndarray:
        """The image (H, W) uint8/uint16 of frame ``index`` logged at ``timestamp_ns`` (read-only)."""
        timestamp_ns, index = int(timestamp_ns), int(index)
        for chunk in self._candidates(timestamp_ns):
            found = [record for record in self._records(chunk) if isinstance(record, Message)
                     and record.channel_id in self._image_ids and record.log_time == timestamp_ns]
            if len(found) > 1:
                found = [record for record in found if record.sequence == (index & 0xFFFFFFFF)] or found[:1]
            if found:
                try:
                    image, _, _, _ = wire.decode_raw_image(found[0].data)
                except wire.WireError as bad:
                    raise CorruptRecording(f"{self._recording.name} is corrupt: image message at log time "
                                           f"{timestamp_ns} ({bad})") from None
                return image
        raise RecordingError(f"{self._recording.name} holds no image of frame {index} at {timestamp_ns} ns")
