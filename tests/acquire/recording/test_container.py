"""Tests of acquire/recording/container.py: MCAP records framed within bounds, chunks opened within bounds, summaries."""

import dataclasses
import io
import struct

import pytest
from mcap.opcode import Opcode
from mcap.records import Chunk, Message, Schema
from mcap.writer import CompressionType, Writer

from livedic.acquire.recording import container
from livedic.acquire.recording.container import Damaged, RecordScan, ScanEnd

N_MESSAGES = 12


def _mcap(compression=CompressionType.NONE, chunk_size=200):
    """A small MCAP file's bytes: one schema, one channel, ``N_MESSAGES`` messages in several chunks."""
    out = io.BytesIO()
    writer = Writer(out, chunk_size=chunk_size, compression=compression)
    writer.start("test", "")
    schema = writer.register_schema("s", "raw", b"schema")
    channel = writer.register_channel("/t", "raw", schema)
    for i in range(N_MESSAGES):
        writer.add_message(channel, i, bytes([i]) * 40, i)
    writer.finish()
    return out.getvalue()


def _scan(data, end=None):
    f = io.BytesIO(data)
    scan = RecordScan(f, len(container.MAGIC), len(data) if end is None else end)
    return scan, [(offset, opcode, length) for offset, opcode, length in scan]


def _chunks(data):
    f = io.BytesIO(data)
    return [container.read_record(f, opcode, length) for _, opcode, length in RecordScan(f, 8, len(data))
            if opcode == Opcode.CHUNK]


# ----------------------------------------------------------------------------- RecordScan

def test_complete_file_scans_to_data_end_with_records_back_to_back():
    data = _mcap()
    scan, records = _scan(data)
    assert scan.stop is ScanEnd.DATA_END and scan.stop.complete
    assert records[0][:2] == (8, Opcode.HEADER)
    for (offset, _, length), (following, _, _) in zip(records, records[1:]):
        assert following == offset + 9 + length                   # 9 = opcode + length before each body
    assert scan.valid_bytes == records[-1][0] + 9 + records[-1][2]
    assert sum(opcode == Opcode.CHUNK for _, opcode, _ in records) > 1


def test_a_cut_file_stops_at_the_last_whole_record():
    data = _mcap()
    _, whole = _scan(data)
    ends = [offset + 9 + length for offset, _, length in whole]
    for cut in range(9, len(data), 7):
        scan, records = _scan(data[:cut])
        assert records == [r for r, end in zip(whole, ends) if end <= cut]
        assert scan.valid_bytes == max([8] + [end for end in ends if end <= cut])
        assert scan.stop in (ScanEnd.PARTIAL, ScanEnd.END_OF_RANGE, ScanEnd.DATA_END)
        assert scan.stop.complete is (scan.stop is ScanEnd.DATA_END)


def test_a_range_ending_on_a_record_end_is_end_of_range():
    data = _mcap()
    _, whole = _scan(data)
    end = whole[3][0] + 9 + whole[3][2]
    scan, records = _scan(data, end=end)
    assert scan.stop is ScanEnd.END_OF_RANGE and records == whole[:4] and not scan.stop.complete


def test_zeros_end_the_scan_where_the_data_ends():
    data = _mcap()
    _, whole = _scan(data)
    keep = whole[4][0]
    scan, records = _scan(data[:keep] + bytes(1000))
    assert scan.stop is ScanEnd.ZEROS and records == whole[:4] and scan.valid_bytes == keep


def test_a_record_claiming_more_than_the_cap_is_too_large_and_never_read():
    claimed = container.MAX_RECORD_BYTES + 1
    data = container.MAGIC + struct.pack("<BQ", Opcode.CHUNK, claimed)
    scan = RecordScan(io.BytesIO(data), 8, 1 << 40)            # a range that seems to hold it
    assert list(scan) == [] and scan.stop is ScanEnd.TOO_LARGE and scan.claimed == claimed


# ----------------------------------------------------------------------------- records

def test_parse_record_round_trips_a_record():
    from mcap.data_stream import RecordBuilder

    schema = Schema(id=3, name="livedic.X", encoding="protobuf", data=b"\x01\x02")
    builder = RecordBuilder()
    schema.write(builder)
    body = builder.end()[9:]
    assert container.parse_record(Opcode.SCHEMA, body) == schema


def test_fields_running_past_their_record_are_damaged():
    with pytest.raises(Damaged, match="a field runs past the end of its record"):
        container.parse_record(Opcode.SCHEMA, struct.pack("<HI", 1, 1000) + b"x")
    with pytest.raises(Damaged, match="shorter than its header"):
        container.parse_record(Opcode.MESSAGE, bytes(container.MESSAGE_HEADER_BYTES - 1))
    message = container.parse_record(Opcode.MESSAGE, struct.pack("<HIQQ", 4, 5, 6, 7) + b"data")
    assert isinstance(message, Message) and (message.channel_id, message.sequence, message.data) == (4, 5, b"data")


def test_read_record_at_checks_what_the_index_points_to():
    data = _mcap()
    _, whole = _scan(data)
    offset, _, length = next(r for r in whole if r[1] == Opcode.CHUNK)
    f = io.BytesIO(data)
    assert isinstance(container.read_record_at(f, offset, length + 9, Opcode.CHUNK), Chunk)
    with pytest.raises(Damaged, match="no chunk record where the index points"):
        container.read_record_at(f, offset + 1, length + 9, Opcode.CHUNK)
    with pytest.raises(Damaged, match="no metadata record"):
        container.read_record_at(f, offset, length + 9, Opcode.METADATA)


# ----------------------------------------------------------------------------- chunks

@pytest.mark.parametrize("compression", [CompressionType.NONE, CompressionType.LZ4, CompressionType.ZSTD])
def test_open_chunk_gives_every_message_in_order(compression):
    chunks = _chunks(_mcap(compression))
    messages = [r for chunk in chunks for r in container.open_chunk(chunk) if isinstance(r, Message)]
    assert [m.log_time for m in messages] == list(range(N_MESSAGES))
    assert [m.data for m in messages] == [bytes([i]) * 40 for i in range(N_MESSAGES)]


@pytest.mark.parametrize("compression, change, match", [
    (CompressionType.NONE, dict(uncompressed_size=container.MAX_CHUNK_BYTES + 1), "claims"),
    (CompressionType.NONE, dict(compression="brotli"), "unsupported chunk compression 'brotli'"),
    (CompressionType.NONE, dict(uncompressed_crc=1), "CRC mismatch"),
    (CompressionType.NONE, dict(uncompressed_size=5), "its header says 5"),
    (CompressionType.LZ4, dict(uncompressed_size=5), "lz4 chunk holds more"),
    (CompressionType.ZSTD, dict(uncompressed_size=5), "zstd frame claims more"),
    (CompressionType.ZSTD, dict(data=b"\x28\xb5\x2f\xfd garbage"), "zstd decompression failed"),
])
def test_chunks_that_do_not_hold_what_they_claim_are_damaged(compression, change, match):
    chunk = _chunks(_mcap(compression))[0]
    with pytest.raises(Damaged, match=match):
        container.open_chunk(dataclasses.replace(chunk, **change))


# ----------------------------------------------------------------------------- summary

def test_summary_of_a_complete_file():
    data = _mcap()
    summary, problem = container.read_summary(io.BytesIO(data), len(data), 8)
    assert problem == "" and [c.topic for c in summary.channels.values()] == ["/t"]
    assert len(summary.chunk_indexes) == len(_chunks(data)) > 1
    assert [c.chunk_start_offset for c in summary.chunk_indexes] == sorted(c.chunk_start_offset
                                                                          for c in summary.chunk_indexes)
    assert summary.statistics.message_count == N_MESSAGES


def test_no_summary_is_not_a_problem():
    data = _mcap()
    cut = data[:len(data) // 2]
    assert container.read_summary(io.BytesIO(cut), len(cut), 8) == (None, "it does not end with an MCAP footer (no index)")
    assert container.read_summary(io.BytesIO(data[:20]), 20, 8) == (None, "")        # too short for a footer
    without = bytearray(data)
    struct.pack_into("<Q", without, len(data) - 8 - 29 + 9, 0)          # footer.summary_start = 0: none written
    assert container.read_summary(io.BytesIO(without), len(data), 8) == (None, "")


def test_damaged_summaries_say_what_is_wrong():
    data = bytearray(_mcap())
    footer_start = len(data) - 8 - 29
    (summary_start,) = struct.unpack_from("<Q", data, footer_start + 9)
    flipped = bytearray(data)
    flipped[summary_start + 20] ^= 0xFF
    assert container.read_summary(io.BytesIO(flipped), len(data), 8) == (None, "its summary fails its CRC")
    outside = bytearray(data)
    struct.pack_into("<Q", outside, footer_start + 9, len(data) + 100)
    assert container.read_summary(io.BytesIO(outside), len(data), 8) == (None, "its footer points outside the file")
    footer = bytearray(data)
    footer[footer_start] = Opcode.CHUNK
    assert container.read_summary(io.BytesIO(footer), len(data), 8) == (None, "its footer is damaged")
