"""What a livedic recording (MCAP) contains: topics, schemas and their wire codecs.

The format lives in ``livedic.acquire``: this module (topics, schemas, codecs,
session metadata as strings), ``acquire.recording.container`` (MCAP records read with bounds,
chunks written in livedic's layout) and ``acquire.recording.reader`` (the readers,
``recover``). ``acquire.recording.writer`` writes live sessions with them. The format is
documented for people in ``docs/guide/recording-format.md``.

The ``livedic.*`` protobuf message types are built at run time from a
``descriptor_pb2.FileDescriptorProto`` (no protoc, no generated code) in a private
descriptor pool. Their serialized ``FileDescriptorSet`` is stored as the MCAP
schema, so Foxglove, ``rerun mcap convert`` and ``mcap-protobuf-support`` decode
them without livedic.

The two hot messages, ``foxglove.RawImage`` and ``livedic.FrameResults``, are
encoded and decoded here by hand (protobuf wire format, fixed-width packed
arrays) so that a 1 MP image costs one copy on write and none on read, and a
result array is one ``numpy.frombuffer``. ``livedic.StrainField`` is encoded by
the same hand encoder (the protobuf library took ~0.3 ms for 1,000 points, the
hand encoder ~0.02 ms: it runs in the tracking thread every frame) and decoded by
the protobuf library (offline only). ``livedic.ExtensometerSample`` and
``livedic.ForceSample`` (a few scalars) use the library both ways. The tests
check that the hand codecs agree with the protobuf library in both directions.

Nothing read from a recording is ever unpickled or evaluated: payloads are
protobuf or JSON (``json.loads``) only.
"""

import json
import struct
import sys

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

# ----------------------------------------------------------------------------- topics

TOPIC_IMAGE = "/camera/image"
TOPIC_FRAME_INFO = "/camera/frame_info"
TOPIC_RESULTS = "/dic/results"
TOPIC_STRAIN = "/dic/strain"
TOPIC_EXTENSOMETERS = "/dic/extensometers"
TOPIC_FORCE = "/machine/force"
TOPIC_EVENTS = "/livedic/events"
TOPIC_SESSION = "/livedic/session"

METADATA_NAME = "livedic.session"        # MCAP Metadata record with the session metadata
RECOVERY_METADATA_NAME = "livedic.recovery"  # added by ``recover``
FORMAT_VERSION = "1"
FORMAT_KEY = "livedic.format_version"    # reserved session keys (added by the recorder)
JSON_KEYS_KEY = "livedic.json_keys"

RAW_IMAGE_SCHEMA = "foxglove.RawImage"
FRAME_RESULTS_SCHEMA = "livedic.FrameResults"
FRAME_INFO_SCHEMA = "livedic.FrameInfo"
STRAIN_FIELD_SCHEMA = "livedic.StrainField"
EXTENSOMETER_SAMPLE_SCHEMA = "livedic.ExtensometerSample"
FORCE_SAMPLE_SCHEMA = "livedic.ForceSample"
EVENT_SCHEMA = "livedic.Event"
SESSION_SCHEMA = "livedic.Session"

IMAGE_FRAME_ID = "camera"
ENCODING_DTYPES = {"mono8": np.dtype("u1"), "8UC1": np.dtype("u1"),
                   "mono16": np.dtype("<u2"), "16UC1": np.dtype("<u2")}
DEFAULT_PIXEL_FORMAT = {np.dtype("u1"): "Mono8", np.dtype("u2"): "Mono16"}
EVENT_LEVELS = ("info", "warning", "error")

# ----------------------------------------------------------------------------- livedic.* schemas

_F = descriptor_pb2.FieldDescriptorProto

# FrameResults: (name, number, protobuf type, repeated, meaning). Arrays are packed.
# Fixed-width element types (fixed32, sfixed32, double, bool) keep the hand codec a
# plain numpy view; bool is a packed varint of 0/1, one byte each.
FRAME_RESULTS_FIELDS = (
    ("frame_index", 1, _F.TYPE_UINT64, False, "index of the frame these results belong to"),
    ("timestamp_ns", 2, _F.TYPE_INT64, False, "that frame's timestamp (ns), equal to the message log_time"),
    ("point_id", 3, _F.TYPE_FIXED32, True, "point identifier, stable over the session"),
    ("x", 4, _F.TYPE_DOUBLE, True, "point position in the reference image, column (px)"),
    ("y", 5, _F.TYPE_DOUBLE, True, "point position in the reference image, row (px)"),
    ("u", 6, _F.TYPE_DOUBLE, True, "displacement along x / columns (px); NaN where not ok"),
    ("v", 7, _F.TYPE_DOUBLE, True, "displacement along y / rows (px); NaN where not ok"),
    ("zncc", 8, _F.TYPE_DOUBLE, True, "zero-normalised cross-correlation of the match, -1..1"),
    ("ok", 9, _F.TYPE_BOOL, True, "1 where the point was tracked, 0 where not"),
    ("ux", 10, _F.TYPE_DOUBLE, True, "du/dx (optional, first-order methods)"),
    ("uy", 11, _F.TYPE_DOUBLE, True, "du/dy (optional)"),
    ("vx", 12, _F.TYPE_DOUBLE, True, "dv/dx (optional)"),
    ("vy", 13, _F.TYPE_DOUBLE, True, "dv/dy (optional)"),
    ("status", 14, _F.TYPE_SFIXED32, True, "dic.status.Status code per point (optional)"),
    ("iterations", 15, _F.TYPE_FIXED32, True, "sub-pixel iterations per point (optional)"),
    ("method", 16, _F.TYPE_STRING, False, "search+subpixel method, e.g. 'improved-wso+icgn1'"),
    ("processing_ns", 17, _F.TYPE_INT64, False, "tracker compute time for this frame (ns)"),
    ("latency_ns", 18, _F.TYPE_INT64, False, "frame arrival to results ready, host clock (ns)"),
    ("reference_frame_index", 19, _F.TYPE_UINT64, False, "frame used as reference (0 unless updated)"),
    ("dropped_frames", 20, _F.TYPE_UINT32, False, "frames dropped (not tracked) since the previous result"),
)
REQUIRED_ARRAYS = ("point_id", "x", "y", "u", "v", "zncc", "ok")
OPTIONAL_ARRAYS = ("ux", "uy", "vx", "vy", "status", "iterations")
RESULT_SCALARS = ("method", "processing_ns", "latency_ns", "reference_frame_index", "dropped_frames")

# StrainField: one message per frame with strain, arrays in the order of /dic/results' points.
STRAIN_FIELD_FIELDS = (
    ("frame_index", 1, _F.TYPE_UINT64, False, "index of the frame this strain belongs to"),
    ("timestamp_ns", 2, _F.TYPE_INT64, False, "that frame's timestamp (ns), equal to the message log_time"),
    ("point_id", 3, _F.TYPE_FIXED32, True, "point identifier, as on /dic/results"),
    ("exx", 4, _F.TYPE_DOUBLE, True, "strain along x / columns (measure below); NaN where status != 0"),
    ("eyy", 5, _F.TYPE_DOUBLE, True, "strain along y / rows; NaN where status != 0"),
    ("exy", 6, _F.TYPE_DOUBLE, True, "tensor shear strain (gamma_xy / 2); NaN where status != 0"),
    ("e1", 7, _F.TYPE_DOUBLE, True, "major principal strain; NaN where status != 0"),
    ("e2", 8, _F.TYPE_DOUBLE, True, "minor principal strain; NaN where status != 0"),
    ("status", 9, _F.TYPE_SFIXED32, True, "dic.strain.StrainStatus code per point (0: strain measured)"),
    ("measure", 10, _F.TYPE_STRING, False, "engineering, green or true (Hencky)"),
    ("window", 11, _F.TYPE_UINT32, False, "points a side of the least-squares window (0: not given)"),
    ("vsg_px", 12, _F.TYPE_DOUBLE, False, "virtual strain gauge (px): (window - 1) x step + subset"),
)
STRAIN_ARRAYS = ("point_id", "exx", "eyy", "exy", "e1", "e2", "status")
STRAIN_DTYPES = {"point_id": np.dtype(np.uint32), "status": np.dtype(np.int32)}   # the rest float64

# ExtensometerSample: one message per extensometer per frame (Foxglove plots
# /dic/extensometers{name=="axial"}.eng_strain).
EXTENSOMETER_SAMPLE_FIELDS = (
    ("frame_index", 1, _F.TYPE_UINT64, False, "index of the frame"),
    ("timestamp_ns", 2, _F.TYPE_INT64, False, "that frame's timestamp (ns), equal to the message log_time"),
    ("name", 3, _F.TYPE_STRING, False, "extensometer name: axial, transverse, or as given"),
    ("l0_px", 4, _F.TYPE_DOUBLE, False, "reference length L0 (px)"),
    ("l_px", 5, _F.TYPE_DOUBLE, False, "current length L (px); NaN where not ok"),
    ("eng_strain", 6, _F.TYPE_DOUBLE, False, "engineering strain (L - L0) / L0; NaN where not ok"),
    ("true_strain", 7, _F.TYPE_DOUBLE, False, "true strain ln(L / L0); NaN where not ok"),
    ("ok", 8, _F.TYPE_BOOL, False, "true where both ends were measured"),
    ("status", 9, _F.TYPE_INT32, False, "dic.strain.extensometer.ExtensometerStatus code (0: measured)"),
)

# ForceSample: the testing machine's force on one tracked frame (Foxglove plots
# /machine/force.force_N and .stress_MPa against time).
FORCE_SAMPLE_FIELDS = (
    ("frame_index", 1, _F.TYPE_UINT64, False, "index of the frame"),
    ("timestamp_ns", 2, _F.TYPE_INT64, False, "that frame's timestamp (ns), equal to the message log_time"),
    ("force_N", 3, _F.TYPE_DOUBLE, False, "force at the frame's time (N); NaN when the load had no value"),
    ("stress_MPa", 4, _F.TYPE_DOUBLE, False, "engineering stress force_N / A0 (MPa); NaN without a cross-section"),
    ("ok", 5, _F.TYPE_BOOL, False, "true where force_N is a number"),
    ("source", 6, _F.TYPE_STRING, False, "the load URI the force came from (--load)"),
)

FRAME_INFO_FIELDS = (
    ("frame_index", 1, _F.TYPE_UINT64, False, "Frame.index (the image's MCAP sequence is this mod 2^32)"),
    ("timestamp_ns", 2, _F.TYPE_INT64, False, "Frame.timestamp_ns"),
    ("pixel_format", 3, _F.TYPE_STRING, False, "Frame.pixel_format, e.g. 'Mono12' (stored as mono16)"),
    ("metadata_json", 4, _F.TYPE_STRING, False, "Frame.metadata as JSON (empty when none)"),
)
EVENT_FIELDS = (
    ("timestamp_ns", 1, _F.TYPE_INT64, False, "when it happened, in the frame clock (ns)"),
    ("kind", 2, _F.TYPE_STRING, False, "drop, camera_lost, recording_stopped, note, ..."),
    ("message", 3, _F.TYPE_STRING, False, "one line for people"),
    ("level", 4, _F.TYPE_STRING, False, "info, warning or error"),
)


def _message_proto(name, fields):
    message = descriptor_pb2.DescriptorProto(name=name)
    for field_name, number, kind, repeated, _ in fields:
        field = message.field.add(name=field_name, number=number, type=kind,
                                  label=_F.LABEL_REPEATED if repeated else _F.LABEL_OPTIONAL)
        if repeated:
            field.options.packed = True
    return message


def _build_file_proto():
    file_proto = descriptor_pb2.FileDescriptorProto(
        name="livedic/recording.proto", package="livedic", syntax="proto3")
    file_proto.message_type.append(_message_proto("FrameResults", FRAME_RESULTS_FIELDS))
    file_proto.message_type.append(_message_proto("FrameInfo", FRAME_INFO_FIELDS))
    file_proto.message_type.append(_message_proto("Event", EVENT_FIELDS))
    file_proto.message_type.append(_message_proto("StrainField", STRAIN_FIELD_FIELDS))
    file_proto.message_type.append(_message_proto("ExtensometerSample", EXTENSOMETER_SAMPLE_FIELDS))
    file_proto.message_type.append(_message_proto("ForceSample", FORCE_SAMPLE_FIELDS))
    session = file_proto.message_type.add(name="Session")
    entry = session.nested_type.add(name="MetadataEntry")
    entry.options.map_entry = True
    entry.field.add(name="key", number=1, type=_F.TYPE_STRING, label=_F.LABEL_OPTIONAL)
    entry.field.add(name="value", number=2, type=_F.TYPE_STRING, label=_F.LABEL_OPTIONAL)
    session.field.add(name="metadata", number=1, type=_F.TYPE_MESSAGE, label=_F.LABEL_REPEATED,
                      type_name=".livedic.Session.MetadataEntry")
    return file_proto


FILE_PROTO = _build_file_proto()
_POOL = descriptor_pool.DescriptorPool()
_POOL.Add(FILE_PROTO)
FrameResults = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(FRAME_RESULTS_SCHEMA))
FrameInfo = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(FRAME_INFO_SCHEMA))
Event = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(EVENT_SCHEMA))
Session = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(SESSION_SCHEMA))
StrainField = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(STRAIN_FIELD_SCHEMA))
ExtensometerSample = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(EXTENSOMETER_SAMPLE_SCHEMA))
ForceSample = message_factory.GetMessageClass(_POOL.FindMessageTypeByName(FORCE_SAMPLE_SCHEMA))


def schema_data(name):
    """Serialized ``FileDescriptorSet`` stored as the MCAP schema ``name`` (encoding "protobuf")."""
    if name == RAW_IMAGE_SCHEMA:
        from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
        from mcap_protobuf.schema import build_file_descriptor_set
        return build_file_descriptor_set(RawImage).SerializeToString()
    if name in (FRAME_RESULTS_SCHEMA, FRAME_INFO_SCHEMA, EVENT_SCHEMA, SESSION_SCHEMA, STRAIN_FIELD_SCHEMA,
                EXTENSOMETER_SAMPLE_SCHEMA, FORCE_SAMPLE_SCHEMA):
        return descriptor_pb2.FileDescriptorSet(file=[FILE_PROTO]).SerializeToString()
    raise KeyError(name)


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


def _iter_fields(buf, start=0, end=None):
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

def image_encoding(image):
    """RawImage encoding name and canonical pixel format for a 2-D uint8/uint16 image."""
    if not isinstance(image, np.ndarray) or image.ndim != 2:
        raise ValueError(f"a frame image must be a 2-D numpy array, got "
                         f"{type(image).__name__} with shape {getattr(image, 'shape', None)}")
    if image.dtype == np.uint8:
        return "mono8"
    if image.dtype.kind == "u" and image.dtype.itemsize == 2:
        return "mono16"
    raise ValueError(f"a frame image must be uint8 or uint16, got {image.dtype}")


def encode_raw_image(image, timestamp_ns, frame_id=IMAGE_FRAME_ID):
    """``foxglove.RawImage`` bytes for a 2-D uint8 (mono8) or uint16 (mono16, little-endian) image.

    Field order and encoding are those of ``RawImage.SerializeToString()``; the pixels are
    copied once, into the returned bytes.
    """
    return b"".join(raw_image_parts(image, timestamp_ns, frame_id))


def raw_image_parts(image, timestamp_ns, frame_id=IMAGE_FRAME_ID):
    """``encode_raw_image``'s bytes in three parts, ``(head, pixels, tail)``, the pixels not copied.

    ``pixels`` is a flat memoryview of ``image`` (of a contiguous little-endian copy when the
    image is strided or big-endian): a writer copies it once, where it keeps the message
    (``acquire.recording.container.ChunkedWriter.add`` takes the parts), instead of a copy into a
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
    head = [_len_field(1, len(stamp)), stamp]
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
    return b"".join(head), memoryview(image).cast("B"), tail


def decode_raw_image(data):
    """Decode ``foxglove.RawImage`` bytes without copying the pixels.

    Returns ``(image, encoding, timestamp_ns, frame_id)``; ``image`` is a read-only
    view into ``data`` (uint8, or uint16 for mono16/16UC1). Raises ``WireError`` for
    anything that is not a mono8/mono16 image with consistent width, height and step.
    """
    buf = memoryview(data).cast("B") if not isinstance(data, bytes) else data
    width = height = step = 0
    encoding = frame_id = ""
    pixels = None
    timestamp_ns = None
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
_ARRAY_DTYPES = {_F.TYPE_DOUBLE: np.dtype("<f8"), _F.TYPE_FIXED32: np.dtype("<u4"),
                 _F.TYPE_SFIXED32: np.dtype("<i4"), _F.TYPE_BOOL: np.dtype("u1")}
_ELEMENT_WIRE = {_F.TYPE_DOUBLE: _WIRE_I64, _F.TYPE_FIXED32: _WIRE_I32, _F.TYPE_SFIXED32: _WIRE_I32,
                 _F.TYPE_BOOL: _WIRE_VARINT}
RESULT_DTYPES = {"point_id": np.dtype(np.uint32), "ok": np.dtype(bool), "status": np.dtype(np.int32),
                 "iterations": np.dtype(np.uint32)}   # every other array is float64


def encode_results(values):
    """``livedic.FrameResults`` bytes from a dict of already-validated values.

    Arrays must be 1-D numpy arrays of equal length with the dtypes of ``RESULT_DTYPES``
    (float64 otherwise); optional arrays may be absent or None. Matches
    ``FrameResults(...).SerializeToString()`` byte for byte.
    """
    return _encode_fields(FRAME_RESULTS_FIELDS, values)


def encode_strain(values):
    """``livedic.StrainField`` bytes from a dict of already-validated values.

    Arrays (``STRAIN_ARRAYS``) must be 1-D numpy arrays of equal length with the dtypes of
    ``STRAIN_DTYPES`` (float64 otherwise). Matches ``StrainField(...).SerializeToString()``
    byte for byte; ``StrainField.FromString`` decodes it.
    """
    return _encode_fields(STRAIN_FIELD_FIELDS, values)


def _encode_fields(fields, values):
    """Protobuf bytes of the message described by ``fields`` (the spec tuples above), in field order.

    Packed arrays are one copy of the numpy data; scalars follow proto3 (zero, empty: not written).
    """
    parts = []
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
            parts += [_len_field(number, payload.nbytes), memoryview(payload).cast("B")]
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


def decode_results(data):
    """Dict of numpy arrays and scalars from ``livedic.FrameResults`` bytes (packed or not).

    Required arrays are always present (possibly empty); optional arrays absent from
    the message are None. Raises ``WireError`` when arrays differ in length.
    """
    buf = data if isinstance(data, bytes) else memoryview(data).cast("B")
    pieces = {}
    out = {"frame_index": 0, "timestamp_ns": 0, "method": "", "processing_ns": 0, "latency_ns": 0,
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


# ----------------------------------------------------------------------------- metadata as strings

def json_default(value):
    """``json.dumps`` fallback: numpy values to Python, anything else to its str().

    The format's conversion for ``json.dumps(..., default=json_default)``: session and
    frame metadata go through it (``to_json``). NaN stays NaN here (Python's JSON reads it
    back); strict JSON files are ``stream.output.files.json_text``'s.
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    if hasattr(value, "__fspath__"):
        return str(value.__fspath__())
    return str(value)


def to_json(value):
    """JSON text for ``value``; never raises (unknown types become strings, NaN stays NaN)."""
    try:
        return json.dumps(value, default=json_default, allow_nan=True)
    except (ValueError, TypeError, RecursionError):
        return json.dumps(str(value))


def metadata_to_strings(metadata):
    """String->string map for MCAP: str values as is, everything else as JSON.

    The keys whose values are JSON are listed (as a JSON list) under ``livedic.json_keys``
    so ``metadata_from_strings`` can give back the original types.
    """
    strings, json_keys = {}, []
    for key, value in metadata.items():
        key = str(key)
        if key == JSON_KEYS_KEY:
            continue
        if isinstance(value, str):
            strings[key] = value
        else:
            strings[key] = to_json(value)
            json_keys.append(key)
    strings[JSON_KEYS_KEY] = json.dumps(sorted(json_keys))
    return strings


def metadata_from_strings(strings):
    """Inverse of ``metadata_to_strings``; values that fail to decode stay strings."""
    try:
        json_keys = json.loads(strings.get(JSON_KEYS_KEY, "[]"))
        if not isinstance(json_keys, list):
            json_keys = []
    except (ValueError, RecursionError):
        json_keys = []
    out = {}
    for key, value in strings.items():
        if key == JSON_KEYS_KEY:
            continue
        if key in json_keys:
            try:
                value = json.loads(value)
            except (ValueError, RecursionError):
                pass
        out[key] = value
    return out

