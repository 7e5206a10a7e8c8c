"""Protobuf wire codecs of the hot messages: ``foxglove.RawImage``, ``livedic.FrameResults``, ``livedic.StrainField``.

Encoded and decoded by hand (protobuf wire format, fixed-width packed arrays) so that a 1 MP image costs
one copy on write and none on read, and a result array is one ``numpy.frombuffer``. ``livedic.StrainField``
is encoded by the same hand encoder (the protobuf library took ~0.3 ms for 1,000 points, the hand encoder
~0.02 ms: it runs in the tracking thread every frame) and decoded by the protobuf library (offline only).
``livedic.ExtensometerSample`` and ``livedic.ForceSample`` (a few scalars) use the library both ways. The
tests check that the hand codecs agree with the protobuf library in both directions. A payload that does
not decode is a ``WireError``; nothing read is ever unpickled or evaluated.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np
from google.protobuf import descriptor_pb2

from livedic.acquire.recording.schema import (ENCODING_DTYPES, FRAME_RESULTS_FIELDS, IMAGE_FRAME_ID, OPTIONAL_ARRAYS,
                                              REQUIRED_ARRAYS, STRAIN_FIELD_FIELDS)

_F = descriptor_pb2.FieldDescriptorProto

# ----------------------------------------------------------------------------- protobuf wire helpers

_WIRE_VARINT, _WIRE_I64, _WIRE_LEN, _WIRE_I32 = 0, 1, 2, 5


class WireError(ValueError):
    """A protobuf payload that does not decode (truncated, bad tag, inconsistent arrays)."""


def _varint(value):
    if value < 0:
        value += 1 << 64                     # int64 two's complement, as protobuf does
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def _tag(number, wire):
    return _varint((number << 3) | wire)


def _len_field(number, payload_len):
    return _tag(number, _WIRE_LEN) + _varint(payload_len)


def _read_varint(buf, pos, end):
    result = shift = 0
    while True:
        if pos >= end or shift > 63:
            raise WireError("truncated or overlong varint")
        byte = buf[pos]
        pos += 1
        result |= (byte & 0x7F) << shift
        if byte < 0x80:
            return result & ((1 << 64) - 1), pos
        shift += 7


def _signed64(value):
    return value - (1 << 64) if value >= 1 << 63 else value


def _iter_fields(buf, start: int = 0, end=None):
    """Yield (number, wire, value) for each field; LEN values are (offset, length) into ``buf``."""
    end = len(buf) if end is None else end
    pos = start
    while pos < end:
        key, pos = _read_varint(buf, pos, end)
        number, wire = key >> 3, key & 7
        if number == 0:
            raise WireError("field number 0")
        if wire == _WIRE_VARINT:
            value, pos = _read_varint(buf, pos, end)
        elif wire == _WIRE_I64:
            if pos + 8 > end:
                raise WireError("truncated 64-bit field")
            value, pos = (pos, 8), pos + 8
        elif wire == _WIRE_LEN:
            length, pos = _read_varint(buf, pos, end)
            if length > end - pos:
                raise WireError("length-delimited field runs past the message")
            value, pos = (pos, length), pos + length
        elif wire == _WIRE_I32:
            if pos + 4 > end:
                raise WireError("truncated 32-bit field")
            value, pos = (pos, 4), pos + 4
        else:
            raise WireError(f"unsupported wire type {wire}")
        yield number, wire, value


def _string(buf, value):
    offset, length = value
    try:
        return bytes(buf[offset:offset + length]).decode("utf-8")
    except UnicodeDecodeError:
        raise WireError("string field is not UTF-8") from None


# ----------------------------------------------------------------------------- foxglove.RawImage

def image_encoding(image: np.ndarray) -> str:
    """RawImage encoding name and canonical pixel format for a 2-D uint8/uint16 image."""
    if not isinstance(image, np.ndarray) or image.ndim != 2:
        raise ValueError(f"a frame image must be a 2-D numpy array, got "
                         f"{type(image).__name__} with shape {getattr(image, 'shape', None)}")
    if image.dtype == np.uint8:
        return "mono8"
    if image.dtype.kind == "u" and image.dtype.itemsize == 2:
        return "mono16"
    raise ValueError(f"a frame image must be uint8 or uint16, got {image.dtype}")


def encode_raw_image(image: np.ndarray, timestamp_ns: int, frame_id: str = IMAGE_FRAME_ID) -> bytes:
    """``foxglove.RawImage`` bytes for a 2-D uint8 (mono8) or uint16 (mono16, little-endian) image.

    Field order and encoding are those of ``RawImage.SerializeToString()``; the pixels are
    copied once, into the returned bytes.
    """
    return b"".join(raw_image_parts(image, timestamp_ns, frame_id))


def raw_image_parts(image: np.ndarray, timestamp_ns: int,
                    frame_id: str = IMAGE_FRAME_ID) -> tuple[bytes, memoryview, bytes]:
    """``encode_raw_image``'s bytes in three parts, ``(head, pixels, tail)``, the pixels not copied.

    ``pixels`` is a flat memoryview of ``image`` (of a contiguous little-endian copy when the
    image is strided or big-endian): a writer copies it once, where it keeps the message
    (``acquire.recording.chunked_writer.ChunkedWriter.add`` takes the parts), instead of a copy into a
    payload and another from it.
    """
    encoding = image_encoding(image)
    if encoding == "mono16" and image.dtype != np.dtype("<u2"):
        image = image.astype("<u2")
    if not image.flags.c_contiguous:
        image = np.ascontiguousarray(image)
    height, width = image.shape
    step = width * image.itemsize
    seconds, nanos = divmod(int(timestamp_ns), 1_000_000_000)
    stamp = b""
    if seconds:
        stamp += _tag(1, _WIRE_VARINT) + _varint(seconds)
    if nanos:
        stamp += _tag(2, _WIRE_VARINT) + _varint(nanos)
    head: list[bytes] = [_len_field(1, len(stamp)), stamp]
    if width:
        head += [_tag(2, _WIRE_I32), struct.pack("<I", width)]
    if height:
        head += [_tag(3, _WIRE_I32), struct.pack("<I", height)]
    enc = encoding.encode()
    head += [_len_field(4, len(enc)), enc]
    if step:
        head += [_tag(5, _WIRE_I32), struct.pack("<I", step)]
    nbytes = image.nbytes
    if nbytes:
        head.append(_len_field(6, nbytes))
    tail = b""
    if frame_id:
        fid = frame_id.encode()
        tail = _len_field(7, len(fid)) + fid
    return b"".join(head), image.data.cast("B"), tail


def decode_raw_image(data: bytes | bytearray | memoryview) -> tuple[np.ndarray, str, int | None, str]:
    """Decode ``foxglove.RawImage`` bytes without copying the pixels.

    Returns ``(image, encoding, timestamp_ns, frame_id)``; ``image`` is a read-only
    view into ``data`` (uint8, or uint16 for mono16/16UC1). Raises ``WireError`` for
    anything that is not a mono8/mono16 image with consistent width, height and step.
    """
    buf = memoryview(data).cast("B") if not isinstance(data, bytes) else data
    width = height = step = 0
    encoding = frame_id = ""
    pixels: tuple[int, int] | None = None
    timestamp_ns: int | None = None
    for number, wire, value in _iter_fields(buf):
        if number == 1 and wire == _WIRE_LEN:
            seconds = nanos = 0
            for sub_number, sub_wire, sub_value in _iter_fields(buf, value[0], value[0] + value[1]):
                if sub_number == 1 and sub_wire == _WIRE_VARINT:
                    seconds = _signed64(sub_value)
                elif sub_number == 2 and sub_wire == _WIRE_VARINT:
                    nanos = _signed64(sub_value)
            timestamp_ns = seconds * 1_000_000_000 + nanos
        elif number in (2, 3, 5) and wire == _WIRE_I32:
            (field_value,) = struct.unpack_from("<I", buf, value[0])
            if number == 2:
                width = field_value
            elif number == 3:
                height = field_value
            else:
                step = field_value
        elif number == 4 and wire == _WIRE_LEN:
            encoding = _string(buf, value)
        elif number == 6 and wire == _WIRE_LEN:
            pixels = value
        elif number == 7 and wire == _WIRE_LEN:
            frame_id = _string(buf, value)
    dtype = ENCODING_DTYPES.get(encoding)
    if dtype is None:
        raise WireError(f"image encoding {encoding!r} is not mono8/mono16")
    row_bytes = width * dtype.itemsize
    if width == 0 or height == 0:
        raise WireError(f"image has size {width}x{height}")
    if step < row_bytes:
        raise WireError(f"image step {step} is less than width*{dtype.itemsize} = {row_bytes}")
    offset, length = pixels if pixels is not None else (0, 0)
    if length < step * (height - 1) + row_bytes:
        raise WireError(f"image data has {length} bytes, {width}x{height} step {step} needs "
                        f"{step * (height - 1) + row_bytes}")
    # a view into the message bytes (read-only, possibly unaligned or with padded rows: numpy copes)
    image = np.ndarray(shape=(height, width), dtype=dtype, buffer=buf, offset=offset,
                       strides=(step, dtype.itemsize))
    if image.dtype.byteorder not in ("=", "|") and sys.byteorder != "little":
        image = image.astype(image.dtype.newbyteorder("="))
    return image, encoding, timestamp_ns, frame_id


# ----------------------------------------------------------------------------- livedic.FrameResults

_RESULT_SPEC = {name: (number, kind, repeated) for name, number, kind, repeated, _ in FRAME_RESULTS_FIELDS}
_RESULT_BY_NUMBER = {number: (name, kind, repeated) for name, (number, kind, repeated) in _RESULT_SPEC.items()}
_ARRAY_DTYPES: dict[int, np.dtype] = {_F.TYPE_DOUBLE: np.dtype("<f8"), _F.TYPE_FIXED32: np.dtype("<u4"),
                                     _F.TYPE_SFIXED32: np.dtype("<i4"), _F.TYPE_BOOL: np.dtype("u1")}
_ELEMENT_WIRE = {_F.TYPE_DOUBLE: _WIRE_I64, _F.TYPE_FIXED32: _WIRE_I32, _F.TYPE_SFIXED32: _WIRE_I32,
                 _F.TYPE_BOOL: _WIRE_VARINT}
RESULT_DTYPES = {"point_id": np.dtype(np.uint32), "ok": np.dtype(bool), "status": np.dtype(np.int32),
                 "iterations": np.dtype(np.uint32), "stereo_status": np.dtype(np.int32)}   # every other array is float64


def encode_results(values: Mapping[str, Any]) -> bytes:
    """``livedic.FrameResults`` bytes from a dict of already-validated values.

    Arrays must be 1-D numpy arrays of equal length with the dtypes of ``RESULT_DTYPES``
    (float64 otherwise); optional arrays may be absent or None. Matches
    ``FrameResults(...).SerializeToString()`` byte for byte.
    """
    return _encode_fields(FRAME_RESULTS_FIELDS, values)


def encode_strain(values: Mapping[str, Any]) -> bytes:
    """``livedic.StrainField`` bytes from a dict of already-validated values.

    Arrays (``STRAIN_ARRAYS``) must be 1-D numpy arrays of equal length with the dtypes of
    ``STRAIN_DTYPES`` (float64 otherwise). Matches ``StrainField(...).SerializeToString()``
    byte for byte; ``StrainField.FromString`` decodes it.
    """
    return _encode_fields(STRAIN_FIELD_FIELDS, values)


def _encode_fields(fields: tuple[tuple[str, int, int, bool, Any], ...], values: Mapping[str, Any]) -> bytes:
    """Protobuf bytes of the message described by ``fields`` (the spec tuples above), in field order.

    Packed arrays are one copy of the numpy data; scalars follow proto3 (zero, empty: not written).
    """
    parts: list[bytes | memoryview] = []
    for name, number, kind, repeated, _ in fields:
        value = values.get(name)
        if value is None:
            continue
        if repeated:
            if len(value) == 0:
                continue
            if kind == _F.TYPE_BOOL:
                payload = np.asarray(value, dtype=bool).view(np.uint8)
            else:
                payload = np.asarray(value, dtype=_ARRAY_DTYPES[kind])
            payload = np.ascontiguousarray(payload)
            parts += [_len_field(number, payload.nbytes), payload.data.cast("B")]
        elif kind == _F.TYPE_STRING:
            if value:
                raw = str(value).encode("utf-8")
                parts += [_len_field(number, len(raw)), raw]
        elif kind == _F.TYPE_DOUBLE:
            raw = struct.pack("<d", float(value))
            if raw != bytes(8):                  # proto3 writes any double but +0.0 (-0.0 and NaN too)
                parts += [_tag(number, _WIRE_I64), raw]
        else:
            if int(value):
                parts += [_tag(number, _WIRE_VARINT), _varint(int(value))]
    return b"".join(parts)


def decode_results(data: bytes | bytearray | memoryview) -> dict[str, Any]:
    """Dict of numpy arrays and scalars from ``livedic.FrameResults`` bytes (packed or not).

    Required arrays are always present (possibly empty); optional arrays absent from
    the message are None. Raises ``WireError`` when arrays differ in length.
    """
    buf = data if isinstance(data, bytes) else memoryview(data).cast("B")
    pieces: dict[str, list[np.ndarray]] = {}
    out: dict[str, Any] = {"frame_index": 0,
 "timestamp_ns": 0, "method": "", "processing_ns": 0, "latency_ns": 0,
           "reference_frame_index": 0, "dropped_frames": 0}
    for number, wire, value in _iter_fields(buf):
        spec = _RESULT_BY_NUMBER.get(number)
        if spec is None:
            continue                          # unknown field: newer writer
        name, kind, repeated = spec
        if repeated:
            dtype = _ARRAY_DTYPES[kind]
            if wire == _WIRE_LEN:
                offset, length = value
                if kind == _F.TYPE_BOOL:
                    chunk = np.frombuffer(buf, dtype=np.uint8, count=length, offset=offset)
                    if length and chunk.max() >= 0x80:     # multi-byte varints: decode slowly
                        decoded, pos = [], offset
                        while pos < offset + length:
                            item, pos = _read_varint(buf, pos, offset + length)
                            decoded.append(item != 0)
                        chunk = np.array(decoded, dtype=np.uint8)
                else:
                    if length % dtype.itemsize:
                        raise WireError(f"packed field {name} has {length} bytes, not a multiple of "
                                        f"{dtype.itemsize}")
                    chunk = np.frombuffer(buf, dtype=dtype, count=length // dtype.itemsize, offset=offset)
            elif wire == _ELEMENT_WIRE[kind]:
                if wire == _WIRE_VARINT:
                    chunk = np.array([value != 0], dtype=np.uint8)
                else:
                    chunk = np.frombuffer(buf, dtype=dtype, count=1, offset=value[0])
            else:
                raise WireError(f"field {name} has wire type {wire}")
            pieces.setdefault(name, []).append(chunk)
        elif kind == _F.TYPE_STRING:
            if wire != _WIRE_LEN:
                raise WireError(f"field {name} has wire type {wire}")
            out[name] = _string(buf, value)
        else:
            if wire != _WIRE_VARINT:
                raise WireError(f"field {name} has wire type {wire}")
            if kind == _F.TYPE_INT64:
                value = _signed64(value)
            elif kind == _F.TYPE_UINT32:
                value &= 0xFFFFFFFF
            out[name] = value
    length = None
    for name in REQUIRED_ARRAYS + OPTIONAL_ARRAYS:
        chunks = pieces.get(name)
        if chunks is None:
            array = None
        else:
            array = chunks[0] if len(chunks) == 1 else np.concatenate(chunks)
        if array is not None:
            array = array.view(bool) if name == "ok" else array
            if array.dtype.byteorder not in ("=", "|"):
                array = array.astype(array.dtype.newbyteorder("="))
            if length is None:
                length = len(array)
            elif len(array) != length:
                raise WireError(f"result array {name} has {len(array)} entries, others have {length}")
        out[name] = array
    for name in REQUIRED_ARRAYS:
        if out[name] is None:
            if length:
                raise WireError(f"result array {name} is missing")
            out[name] = np.empty(0, dtype=RESULT_DTYPES.get(name, np.float64))
    return out
