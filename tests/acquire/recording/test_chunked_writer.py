"""ChunkedWriter (acquire.recording.chunked_writer) writes its chunks itself: the bytes must be those mcap's own
Writer writes.

The reference is a plain ``mcap.writer.Writer`` given the same calls and flushed where ChunkedWriter's
chunks end (one open chunk: image messages as they come, the data messages together when the data is
written, schema and channel records into whichever chunk is open when they are registered). The files
must be equal byte for byte; mcap's own reader must then read them with every CRC checked.
"""

import io
import random

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType, Writer

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.acquire.recording.chunked_writer import ChunkedWriter

LIBRARY = "livedic/test"
_CODECS = {None: CompressionType.NONE, "lz4": CompressionType.LZ4, "zstd": CompressionType.ZSTD}


class _Reference:
    """mcap's Writer driven as ChunkedWriter lays out its chunks."""

    def __init__(self, stream, compression):
        self.writer = Writer(stream, chunk_size=1 << 62, compression=_CODECS[compression],
                             index_types=IndexType.ALL, use_chunking=True, enable_crcs=True)
        self.writer.start(profile="", library=LIBRARY)
        self.image_open = False
        self.pending = []

    def add(self, kind, channel, log_time, payload, publish_time, sequence):
        data = b"".join(payload) if isinstance(payload, tuple) else bytes(payload)
        if kind == "image":
            self.writer.add_message(channel, log_time, data, publish_time, sequence)
            self.image_open = True
        else:
            self.pending.append((channel, log_time, data, publish_time, sequence))

    def close_image_chunk(self):
        if self.image_open:
            self.writer.flush()
            self.image_open = False

    def write_data(self):
        if self.pending:
            self.close_image_chunk()
            for message in self.pending:
                self.writer.add_message(*message)
            self.writer.flush()
            self.pending = []

    def finish(self):
        self.close_image_chunk()
        self.write_data()
        self.writer.finish()


def _script(seed):
    """A random session: registrations (some after messages), metadata, images given whole or in parts
    (a header, a numpy image's pixels, a trailer), data, and the calls that end chunks."""
    rng = random.Random(seed)
    nrng = np.random.default_rng(seed)
    ops = [("schema", "foxglove.RawImage", b"image schema"), ("channel", rs.TOPIC_IMAGE, 1),
           ("metadata", rs.METADATA_NAME, {"source_uri": "test://"}),
           ("schema", "livedic.FrameResults", b"results schema"), ("channel", rs.TOPIC_RESULTS, 2)]
    channels = [1, 2]
    for i in range(60):
        roll = rng.random()
        if roll < 0.04:
            ops.append(("schema", f"late{i}", b"{}"))
            ops.append(("channel", f"/late/{i}", len([op for op in ops if op[0] == "schema"])))
            channels.append(len(channels) + 1)
        elif roll < 0.06:
            ops.append(("metadata", f"note{i}", {"i": str(i)}))
        elif roll < 0.12:
            ops.append((rng.choice(["close_image_chunk", "write_data", "flush"]),))
        image = nrng.integers(0, 256, size=(rng.choice([1, 7, 64]), rng.choice([3, 40])), dtype=np.uint8)
        payload = (b"head", memoryview(image).cast("B"), b"tail") if rng.random() < 0.5 else image.tobytes()
        kind = "image" if rng.random() < 0.5 else "data"
        ops.append(("add", kind, rng.choice(channels), 1_000 + 10 * i - rng.randrange(30), payload, i, i % 7))
    return ops


def _write_both(ops, compression):
    ours, theirs = io.BytesIO(), io.BytesIO()
    chunked = ChunkedWriter(ours, chunk_bytes=1 << 40, compression=compression, library=LIBRARY)
    reference = _Reference(theirs, compression)
    for op in ops:
        if op[0] == "schema":
            assert chunked.writer.register_schema(op[1], "protobuf", op[2]) == \
                reference.writer.register_schema(op[1], "protobuf", op[2])
        elif op[0] == "channel":
            assert chunked.writer.register_channel(op[1], "protobuf", op[2]) == \
                reference.writer.register_channel(op[1], "protobuf", op[2])
        elif op[0] == "metadata":
            chunked.writer.add_metadata(op[1], op[2])
            reference.writer.add_metadata(op[1], op[2])
        elif op[0] == "add":
            _, kind, channel, log_time, payload, publish_time, sequence = op
            chunked.add(kind, channel, log_time, payload, publish_time=publish_time, sequence=sequence)
            reference.add(kind, channel, log_time, payload, publish_time, sequence)
        elif op[0] == "flush":
            chunked.flush()
            reference.close_image_chunk()
            reference.write_data()
        else:
            getattr(chunked, op[0])()
            getattr(reference, op[0])()
    chunked.finish()
    reference.finish()
    return ours.getvalue(), theirs.getvalue(), chunked


@pytest.mark.parametrize("compression", [None, "lz4", "zstd"])
@pytest.mark.parametrize("seed", range(8))
def test_chunks_are_the_bytes_mcap_writes(compression, seed):
    ops = _script(seed)
    ours, theirs, chunked = _write_both(ops, compression)
    assert ours == theirs
    reader = make_reader(io.BytesIO(ours), validate_crcs=True)
    summary = reader.get_summary()
    assert summary.statistics.chunk_count == chunked.chunks_written == len(summary.chunk_indexes)
    added = [op for op in ops if op[0] == "add"]
    assert summary.statistics.message_count == len(added)
    payloads = sorted((op[2], op[5], b"".join(op[4]) if isinstance(op[4], tuple) else op[4]) for op in added)
    read = sorted((channel.id, message.publish_time, message.data)
                  for _, channel, message in reader.iter_messages(log_time_order=False))
    assert read == payloads


def test_the_first_chunk_carries_the_schemas_and_channels_registered_before_it():
    """The recorder's layout: everything registered first, then the session message alone in a data chunk."""
    ours, theirs = io.BytesIO(), io.BytesIO()
    chunked = ChunkedWriter(ours, chunk_bytes=1 << 20, compression=None, library=LIBRARY)
    reference = _Reference(theirs, None)
    for writer in (chunked.writer, reference.writer):
        for topic in (rs.TOPIC_IMAGE, rs.TOPIC_RESULTS, rs.TOPIC_SESSION):
            writer.register_channel(topic, "protobuf", writer.register_schema(topic, "protobuf", topic.encode()))
    chunked.add("data", 3, 5, b"session", publish_time=9)
    chunked.write_data()
    reference.add("data", 3, 5, b"session", 9, 0)
    reference.write_data()
    image = np.arange(64, dtype=np.uint8).reshape(8, 8)
    chunked.add("image", 1, 6, wire.raw_image_parts(image, 6))
    reference.add("image", 1, 6, wire.encode_raw_image(image, 6), 0, 0)
    chunked.finish()
    reference.finish()
    assert ours.getvalue() == theirs.getvalue()


def test_a_payload_is_copied_when_added():
    """The caller may reuse its image as soon as ``add`` returns (a camera's buffer pool does)."""
    stream = io.BytesIO()
    chunked = ChunkedWriter(stream, chunk_bytes=1 << 20, compression=None, library=LIBRARY)
    channel = chunked.register(rs.TOPIC_IMAGE, rs.RAW_IMAGE_SCHEMA, rs.schema_data(rs.RAW_IMAGE_SCHEMA))
    image = np.zeros((4, 6), np.uint8)
    for i in range(3):
        image[:] = i
        chunked.add("image", channel, i, wire.raw_image_parts(image, i))
    chunked.finish()
    messages = make_reader(io.BytesIO(stream.getvalue()), validate_crcs=True).iter_messages()
    assert [int(wire.decode_raw_image(message.data)[0][0, 0]) for _, _, message in messages] == [0, 1, 2]
