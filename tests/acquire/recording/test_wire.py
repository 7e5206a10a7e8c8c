"""Tests of acquire/recording/wire.py: the hand protobuf codecs agree with the protobuf library, views, bad payloads."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire

T0 = 1_700_000_000_000_000_000


def _image(dtype, shape, seed=0):
    rng = np.random.default_rng(seed)
    top = 255 if dtype == np.uint8 else 65535
    return rng.integers(0, top + 1, size=shape, dtype=dtype)


def _results(n_points=17, seed=1):
    rng = np.random.default_rng(seed)
    u = rng.normal(size=n_points)
    u[-1] = np.nan
    return dict(point_id=np.arange(100, 100 + n_points, dtype=np.uint32), x=rng.uniform(0, 40, n_points),
                y=rng.uniform(0, 24, n_points), u=u, v=rng.normal(size=n_points),
                zncc=rng.uniform(-1, 1, n_points), ok=rng.random(n_points) > 0.3)


def _same(a, b):
    """Equal bit for bit, NaN included."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return a.shape == b.shape and bool(np.all((a.view(np.uint64) == b.view(np.uint64)) | (np.isnan(a) & np.isnan(b))))


# ----------------------------------------------------------------------------- foxglove.RawImage

@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 9), w=st.integers(1, 9), wide=st.booleans(), ts=st.integers(0, 2**63 - 1))
def test_raw_image_codec_matches_protobuf(h, w, wide, ts):
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
    from google.protobuf.timestamp_pb2 import Timestamp

    image = _image(np.uint16 if wide else np.uint8, (h, w), seed=h * 10 + w)
    ours = wire.encode_raw_image(image, ts)
    theirs = RawImage(timestamp=Timestamp(seconds=ts // 10**9, nanos=ts % 10**9), frame_id=rs.IMAGE_FRAME_ID,
                      width=w, height=h, encoding="mono16" if wide else "mono8", step=w * image.itemsize,
                      data=image.astype(image.dtype.newbyteorder("<")).tobytes())
    assert ours == theirs.SerializeToString()
    decoded, encoding, stamp, _ = wire.decode_raw_image(theirs.SerializeToString())
    assert np.array_equal(decoded, image) and stamp == ts and encoding == theirs.encoding


def test_raw_image_with_row_padding_decodes_as_a_view():
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    padded = np.arange(6 * 12, dtype=np.uint16).reshape(6, 12)
    data = RawImage(width=10, height=6, step=24, encoding="16UC1", data=padded.tobytes()).SerializeToString()
    image = wire.decode_raw_image(data)[0]
    assert np.array_equal(image, padded[:, :10]) and not image.flags.writeable


def test_parts_join_to_the_encoding_and_the_pixels_are_not_copied():
    image = _image(np.uint8, (5, 7))
    head, pixels, tail = wire.raw_image_parts(image, T0, frame_id="cam-2")
    assert head + bytes(pixels) + tail == wire.encode_raw_image(image, T0, frame_id="cam-2")
    image[0, 0] ^= 0xFF                      # the view sees the change: no copy was made
    assert pixels[0] == image[0, 0]
    decoded, encoding, stamp, frame_id = wire.decode_raw_image(head + bytes(pixels) + tail)
    assert (encoding, stamp, frame_id) == ("mono8", T0, "cam-2") and np.array_equal(decoded, image)


def test_strided_and_big_endian_images_round_trip_as_seen():
    base = _image(np.uint16, (8, 10))
    for image in (base[::2, 1::3], base.astype(">u2"), np.asfortranarray(base)):
        decoded, encoding, _, _ = wire.decode_raw_image(wire.encode_raw_image(image, 7))
        assert encoding == "mono16" and decoded.dtype == np.uint16 and np.array_equal(decoded, image)


def test_timestamp_zero_is_zero_and_absent_timestamp_is_none():
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    image = np.ones((2, 3), np.uint8)
    assert wire.decode_raw_image(wire.encode_raw_image(image, 0))[2] == 0
    bare = RawImage(width=3, height=2, step=3, encoding="mono8", data=image.tobytes()).SerializeToString()
    assert wire.decode_raw_image(bare)[2] is None


@pytest.mark.parametrize("image, match", [
    (np.zeros((2, 3, 3), np.uint8), "2-D"),
    (np.zeros(4, np.uint8), "2-D"),
    ([[1, 2], [3, 4]], "numpy array"),
    (np.zeros((2, 3), np.float32), "uint8 or uint16"),
    (np.zeros((2, 3), np.int16), "uint8 or uint16"),
])
def test_only_2d_uint8_or_uint16_images_encode(image, match):
    with pytest.raises(ValueError, match=match):
        wire.encode_raw_image(image, 0)


@pytest.mark.parametrize("fields, match", [
    (dict(width=3, height=2, step=3, encoding="rgb8", data=bytes(6)), "not mono8/mono16"),
    (dict(width=0, height=2, step=3, encoding="mono8", data=bytes(6)), "size 0x2"),
    (dict(width=3, height=2, step=2, encoding="mono8", data=bytes(6)), "step 2 is less than"),
    (dict(width=3, height=2, step=6, encoding="mono16", data=bytes(11)), "11 bytes"),
    (dict(width=3, height=2, step=3, encoding="mono8"), "0 bytes"),
])
def test_inconsistent_images_are_wire_errors(fields, match):
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    with pytest.raises(wire.WireError, match=match):
        wire.decode_raw_image(RawImage(**fields).SerializeToString())


def test_truncated_image_message_is_a_wire_error():
    data = wire.encode_raw_image(np.ones((4, 4), np.uint8), T0)
    with pytest.raises(wire.WireError, match="runs past the message"):
        wire.decode_raw_image(data[:-12])


# ----------------------------------------------------------------------------- livedic.FrameResults

def test_results_codec_matches_protobuf_both_ways():
    values = _results()
    values.update(frame_index=2**40, timestamp_ns=T0, status=np.array([-3] * 17, np.int32), method="m",
                  latency_ns=-5, dropped_frames=2**32 - 1)
    ours = wire.encode_results(values)
    as_lists = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in values.items()}
    theirs = rs.FrameResults(**as_lists)
    assert ours == theirs.SerializeToString()
    back = wire.decode_results(theirs.SerializeToString())
    for key, value in values.items():
        if isinstance(value, np.ndarray):
            assert back[key].tobytes() == value.astype(back[key].dtype).tobytes(), key
        else:
            assert back[key] == value, key


def test_unpacked_repeated_fields_decode_like_packed_ones():
    """proto2-style writers send one element per field: the decoder concatenates them."""
    values = _results(n_points=4)
    message = rs.FrameResults(**{k: v.tolist() for k, v in values.items()})
    unpacked = b"".join(wire._tag(9, wire._WIRE_VARINT) + bytes([int(ok)]) for ok in values["ok"])
    unpacked += b"".join(wire._tag(4, wire._WIRE_I64) + np.float64(x).tobytes() for x in values["x"])
    message.ClearField("ok")
    message.ClearField("x")
    back = wire.decode_results(message.SerializeToString() + unpacked)
    assert back["ok"].tolist() == values["ok"].tolist() and _same(back["x"], values["x"])


def test_empty_message_gives_empty_required_arrays_and_no_optional_ones():
    back = wire.decode_results(b"")
    for name in rs.REQUIRED_ARRAYS:
        assert len(back[name]) == 0 and back[name].dtype == wire.RESULT_DTYPES.get(name, np.float64), name
    assert all(back[name] is None for name in rs.OPTIONAL_ARRAYS)
    assert (back["frame_index"], back["method"], back["timestamp_ns"]) == (0, "", 0)


def test_arrays_of_different_lengths_are_wire_errors():
    values = _results(n_points=5)
    values["v"] = values["v"][:4]
    with pytest.raises(wire.WireError, match="v has 4 entries, others have 5"):
        wire.decode_results(wire.encode_results(values))
    del values["v"]
    with pytest.raises(wire.WireError, match="result array v is missing"):
        wire.decode_results(wire.encode_results(values))


def test_wrong_wire_type_and_unknown_fields():
    with pytest.raises(wire.WireError, match="method has wire type 0"):
        wire.decode_results(wire._tag(16, wire._WIRE_VARINT) + wire._varint(3))
    newer = wire.encode_results(_results(n_points=2)) + wire._tag(99, wire._WIRE_VARINT) + wire._varint(1)
    assert wire.decode_results(newer)["point_id"].tolist() == [100, 101]       # a newer writer's field is skipped


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_decoders_reject_garbage_cleanly(data):
    for decode in (wire.decode_raw_image, wire.decode_results):
        try:
            decode(data)
        except wire.WireError:
            pass


# ----------------------------------------------------------------------------- livedic.StrainField

@settings(max_examples=60, deadline=None)
@given(n=st.integers(0, 40), frame=st.integers(0, 2**64 - 1), ts=st.integers(-2**63, 2**63 - 1),
       window=st.integers(0, 2**32 - 1), vsg=st.floats(allow_nan=False), measure=st.sampled_from(["", "true"]))
def test_strain_hand_encoder_matches_protobuf(n, frame, ts, window, vsg, measure):
    rng = np.random.default_rng(n)
    values = {"frame_index": frame, "timestamp_ns": ts, "point_id": np.arange(n, dtype=np.uint32),
              "status": rng.integers(-2**31, 2**31, n).astype(np.int32), "measure": measure, "window": window,
              "vsg_px": vsg}
    for name in ("exx", "eyy", "exy", "e1", "e2"):
        values[name] = np.where(rng.random(n) < 0.2, np.nan, rng.normal(size=n))
    ours = wire.encode_strain(values)
    theirs = rs.StrainField(**{k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in values.items()})
    assert ours == theirs.SerializeToString()
    back = rs.StrainField.FromString(ours)
    assert _same(np.array(back.exx), values["exx"]) and back.vsg_px == vsg and back.window == window


def test_negative_zero_and_nan_scalars_are_written_positive_zero_is_not():
    assert wire.encode_strain({"vsg_px": 0.0}) == b""
    for value in (-0.0, float("nan")):
        back = rs.StrainField.FromString(wire.encode_strain({"vsg_px": value}))
        assert np.float64(back.vsg_px).tobytes() == np.float64(value).tobytes()
