"""``recover``: a crashed or truncated livedic recording rewritten as a complete, indexed MCAP."""

from __future__ import annotations

import os
from collections import Counter
from datetime import datetime, timezone
from typing import Any

from mcap.records import Channel, Message, Metadata, Schema

from livedic.acquire.atomic_file import AtomicFile
from livedic.acquire.recording import schema as rs
from livedic.acquire.recording.chunked_writer import ChunkedWriter, library_name
from livedic.acquire.recording.errors import RecordingError
from livedic.acquire.recording.reader import Recording

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
    if os.path.realpath(src_path) == os.path.realpath(dst_path) or (
            os.path.exists(dst_path) and os.path.exists(src_path) and os.path.samefile(src_path, dst_path)):
        raise RecordingError(f"recover: destination {dst_path} is the source itself; choose another file")
    if os.path.exists(dst_path) and not overwrite:
        raise RecordingError(f"recover: {dst_path} already exists; pass overwrite=True to replace it")
    recording = Recording(src_path)
    recording.forget_index()                       # walk every record, whatever the index says
    counts: Counter[str] = Counter()
    skipped = 0
    schema_map: dict[int, int] = {}
    channel_map: dict[int, int] = {}
    kinds: dict[int, str] = {}
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
            elif not isinstance(record, Message):
                continue                           # the scan yields schemas, channels, metadata and messages only
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
