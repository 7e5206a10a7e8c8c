"""Tests of acquire/recording/schema.py: the livedic.* message types, their field tables and the stored schemas."""

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from livedic.acquire.recording import schema as rs

TABLES = {rs.FRAME_RESULTS_SCHEMA: rs.FRAME_RESULTS_FIELDS, rs.STRAIN_FIELD_SCHEMA: rs.STRAIN_FIELD_FIELDS,
          rs.EXTENSOMETER_SAMPLE_SCHEMA: rs.EXTENSOMETER_SAMPLE_FIELDS, rs.FORCE_SAMPLE_SCHEMA: rs.FORCE_SAMPLE_FIELDS,
          rs.FRAME_INFO_SCHEMA: rs.FRAME_INFO_FIELDS, rs.EVENT_SCHEMA: rs.EVENT_FIELDS}
CLASSES = {rs.FRAME_RESULTS_SCHEMA: rs.FrameResults, rs.STRAIN_FIELD_SCHEMA: rs.StrainField,
           rs.EXTENSOMETER_SAMPLE_SCHEMA: rs.ExtensometerSample, rs.FORCE_SAMPLE_SCHEMA: rs.ForceSample,
           rs.FRAME_INFO_SCHEMA: rs.FrameInfo, rs.EVENT_SCHEMA: rs.Event}


@pytest.mark.parametrize("name", TABLES)
def test_field_tables_have_unique_names_and_numbers_and_a_meaning(name):
    fields = TABLES[name]
    assert len({f[0] for f in fields}) == len(fields) and len({f[1] for f in fields}) == len(fields)
    assert [f[1] for f in fields] == list(range(1, len(fields) + 1))       # numbers are never reused
    assert all(isinstance(f[4], str) and f[4] for f in fields)


@pytest.mark.parametrize("name", TABLES)
def test_message_classes_follow_their_tables(name):
    descriptor = CLASSES[name].DESCRIPTOR
    assert descriptor.full_name == name
    for field_name, number, kind, repeated, _ in TABLES[name]:
        field = descriptor.fields_by_name[field_name]
        assert (field.number, field.type) == (number, kind)
        assert field.is_repeated is repeated


def test_array_names_are_the_repeated_fields():
    results_arrays = [f[0] for f in rs.FRAME_RESULTS_FIELDS if f[3]]
    assert sorted(results_arrays) == sorted(rs.REQUIRED_ARRAYS + rs.OPTIONAL_ARRAYS)
    results_scalars = {f[0] for f in rs.FRAME_RESULTS_FIELDS if not f[3]}
    assert set(rs.RESULT_SCALARS) | {"frame_index", "timestamp_ns"} == results_scalars
    assert sorted(f[0] for f in rs.STRAIN_FIELD_FIELDS if f[3]) == sorted(rs.STRAIN_ARRAYS)


@pytest.mark.parametrize("name", list(TABLES) + [rs.SESSION_SCHEMA])
def test_stored_schema_builds_the_same_messages_without_livedic(name):
    """What a reader without livedic does: build the type from the schema bytes, decode livedic's bytes."""
    files = descriptor_pb2.FileDescriptorSet.FromString(rs.schema_data(name))
    pool = descriptor_pool.DescriptorPool()
    for file_proto in files.file:
        pool.Add(file_proto)
    theirs = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))
    if name == rs.SESSION_SCHEMA:
        ours = rs.Session(metadata={"a": "1", "b": "x"})
        assert dict(theirs.FromString(ours.SerializeToString()).metadata) == {"a": "1", "b": "x"}
    else:
        ours = CLASSES[name](timestamp_ns=-5)
        assert theirs.FromString(ours.SerializeToString()).timestamp_ns == -5
    # deterministic: a map field (the session's metadata) is serialised in no fixed order otherwise
    again = theirs.FromString(ours.SerializeToString()).SerializeToString(deterministic=True)
    assert again == ours.SerializeToString(deterministic=True)


def test_arrays_are_packed_and_proto3_drops_defaults():
    message = rs.FrameResults(point_id=[1, 2, 3], ok=[True, False, True])
    data = message.SerializeToString()
    assert data[:2] == bytes([3 << 3 | 2, 12])          # point_id: one length-delimited field of 3 x 4 bytes
    assert rs.FrameResults(frame_index=0, method="").SerializeToString() == b""


def test_raw_image_schema_is_foxglove_s_and_unknown_names_are_key_errors():
    files = descriptor_pb2.FileDescriptorSet.FromString(rs.schema_data(rs.RAW_IMAGE_SCHEMA))
    assert any(m.name == "RawImage" for f in files.file for m in f.message_type)
    with pytest.raises(KeyError):
        rs.schema_data("livedic.Nothing")


def test_encodings_map_to_little_endian_mono_dtypes():
    assert set(rs.ENCODING_DTYPES.values()) == {np.dtype("u1"), np.dtype("<u2")}
    assert rs.ENCODING_DTYPES["mono8"] == rs.ENCODING_DTYPES["8UC1"]
    assert rs.ENCODING_DTYPES["mono16"] == rs.ENCODING_DTYPES["16UC1"]
    assert rs.DEFAULT_PIXEL_FORMAT[np.dtype("u2")] == "Mono16" and rs.EVENT_LEVELS[0] == "info"
