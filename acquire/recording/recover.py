"""``recover``: a crashed or truncated livedic recording rewritten as a complete, indexed MCAP."""

from __future__ import annotations

import os
from collections import Counter
from datetime import datetime, timezone
from typing import Any

from mcap.records import Channel, McapRecord, Message, Metadata, Schema

from livedic.acquire.atomic_file import AtomicFile
from livedic.acquire.recording import schema as rs
from livedic.acquire.recording.chunked_writer import ChunkedWriter, library_name
from livedic.acquire.recording.errors import RecordingError
from livedic.acquire.recording.reader import Recording
from livedic.acquire.recording.records import RecordingInfo

__all__ = ["recover"]


def recover(src: str | os.PathLike[str], dst: str | os.PathLike[str], *, overwrite: bool = False,
            chunk_bytes: int = 1 << 20, compression: str | None = None) -> dict[str, Any]:
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
    _check_destination(src_path, dst_path, overwrite)
    recording = Recording(src_path)
    recording.forget_index()                       # walk every record, whatever the index says
    with AtomicFile(dst_path, binary=True) as out:
        writer = ChunkedWriter(out.handle, chunk_bytes=chunk_bytes, compression=compression,
                               library=library_name("recovered"))
        copy = _RecordCopy(writer, recording)
        for record in recording.records(strict=False):
            copy.add(record)
        writer.writer.add_metadata(rs.RECOVERY_METADATA_NAME, _recovery_metadata(src_path, recording.info, copy))
        writer.finish()
        if os.path.exists(dst_path) and not overwrite:
            raise RecordingError(f"recover: {dst_path} appeared while recovering; it was left as it is")
        out.commit(sync=True)
    return _report(src_path, dst_path, recording, copy)


def _check_destination(src_path: str, dst_path: str, overwrite: bool) -> None:
    """RecordingError when ``dst_path`` is the source itself, or exists and may not be replaced."""
    if os.path.realpath(src_path) == os.path.realpath(dst_path) or (
            os.path.exists(dst_path) and os.path.exists(src_path) and os.path.samefile(src_path, dst_path)):
        raise RecordingError(f"recover: destination {dst_path} is the source itself; choose another file")
    if os.path.exists(dst_path) and not overwrite:
        raise RecordingError(f"recover: {dst_path} already exists; pass overwrite=True to replace it")


class _RecordCopy:
    """What ``recover`` copies into ``writer``, record by record in file order: schemas and channels (renumbered
    as the new file registers them), metadata, and the messages of known channels, counted per topic in
    ``counts``; ``skipped`` counts the messages of channels the file never declared."""

    def __init__(self, writer: ChunkedWriter, recording: Recording) -> None:
        self.writer, self.recording = writer, recording
        self.counts: Counter[str] = Counter()
        self.skipped = 0
        self._schemas: dict[int, int] = {}        # id in the source -> id in the copy
        self._channels: dict[int, int] = {}
        self._kinds: dict[int, str] = {}          # source channel id -> "image" or "data" chunks

    def add(self, record: McapRecord) -> None:
        if isinstance(record, Schema):
            if record.id not in self._schemas:
                self._schemas[record.id] = self.writer.writer.register_schema(record.name, record.encoding,
                                                                              record.data)
        elif isinstance(record, Channel):
            self._add_channel(record)
        elif isinstance(record, Metadata):
            self.writer.writer.add_metadata(record.name, record.metadata)
        elif isinstance(record, Message):
            self._add_message(record)

    def _add_channel(self, record: Channel) -> None:
        if record.id in self._channels or (record.schema_id and record.schema_id not in self._schemas):
            return
        self._channels[record.id] = self.writer.writer.register_channel(
            record.topic, record.message_encoding, self._schemas.get(record.schema_id, 0), dict(record.metadata))
        self._kinds[record.id] = "image" if record.topic in (rs.TOPIC_IMAGE, rs.TOPIC_FRAME_INFO) else "data"

    def _add_message(self, record: Message) -> None:
        if record.channel_id not in self._channels:
            self.skipped += 1
            return
        self.writer.add(self._kinds[record.channel_id], self._channels[record.channel_id], record.log_time,
                        record.data, publish_time=record.publish_time, sequence=record.sequence)
        self.counts[self.recording.channels[record.channel_id].topic] += 1


def _recovery_metadata(src_path: str, info: RecordingInfo, copy: _RecordCopy) -> dict[str, str]:
    """The ``livedic.recovery`` metadata record: what was read, what was copied, and when."""
    return {"source": os.path.abspath(src_path), "source_bytes": str(info.size_bytes),
            "valid_bytes": str(info.valid_bytes), "truncated": "true" if info.truncated else "false",
            "messages": str(sum(copy.counts.values())), "corrupt_chunks": str(info.corrupt_chunks),
            "recovered_at": datetime.now(timezone.utc).isoformat()}


def _report(src_path: str, dst_path: str, recording: Recording, copy: _RecordCopy) -> dict[str, Any]:
    """``recover``'s returned dict (see its docstring), with the note for people."""
    info, counts = recording.info, copy.counts
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
            "corrupt_chunks": info.corrupt_chunks, "skipped_messages": copy.skipped, "note": note}
