"""What a livedic recording (MCAP) contains: topics, schemas and the ``livedic.*`` protobuf message types.

The format lives in ``livedic.acquire.recording``: this module (topics, schemas), ``wire`` (the
hand codecs of the hot messages), ``metadata`` (session metadata as strings), ``container`` and
``chunked_writer`` (MCAP records read with bounds, chunks written in livedic's layout), the readers
(``reader``, ``source``, ``recover``) and ``writer`` (live sessions). The format is documented for
people in ``docs/guide/recording-format.md``.

The ``livedic.*`` protobuf message types are built at run time from a
``descriptor_pb2.FileDescriptorProto`` (no protoc, no generated code) in a private
descriptor pool. Their serialized ``FileDescriptorSet`` is stored as the MCAP
schema, so Foxglove, ``rerun mcap convert`` and ``mcap-protobuf-support`` decode
them without livedic.
"""

import numpy as np
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

# ----------------------------------------------------------------------------- topics

TOPIC_IMAGE = "/camera/image"
TOPIC_FRAME_INFO = "/camera/frame_info"
# A stereo session's second camera; the first (left) keeps /camera/image, so a 2D reader sees the left view.
TOPIC_RIGHT_IMAGE = "/camera/right/image"
TOPIC_RIGHT_FRAME_INFO = "/camera/right/frame_info"
VIEWS = ("left", "right")
VIEW_TOPICS = {"left": (TOPIC_IMAGE, TOPIC_FRAME_INFO), "right": (TOPIC_RIGHT_IMAGE, TOPIC_RIGHT_FRAME_INFO)}
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
ENCODING_DTYPES: dict[str, np.dtype] = {"mono8": np.dtype("u1"), "8UC1": np.dtype("u1"),
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
    # stereo sessions only (``x``..``v`` above are then the left view's)
    ("x_mm", 21, _F.TYPE_DOUBLE, True, "X of the point now (mm, left camera frame; stereo); NaN where not ok in 3D"),
    ("y_mm", 22, _F.TYPE_DOUBLE, True, "Y of the point now (mm; stereo)"),
    ("z_mm", 23, _F.TYPE_DOUBLE, True, "Z of the point now (mm, depth along the left camera's axis; stereo)"),
    ("u_mm", 24, _F.TYPE_DOUBLE, True, "U = X - X at the reference pair (mm; stereo)"),
    ("v_mm", 25, _F.TYPE_DOUBLE, True, "V = Y - Y at the reference pair (mm; stereo)"),
    ("w_mm", 26, _F.TYPE_DOUBLE, True, "W = Z - Z at the reference pair (mm; stereo)"),
    ("stereo_status", 27, _F.TYPE_SFIXED32, True, "dic.stereo.StereoStatus code per point (0: ok in 3D; stereo)"),
    ("right_x", 28, _F.TYPE_DOUBLE, True, "where the point is in the right image now, column (px; stereo)"),
    ("right_y", 29, _F.TYPE_DOUBLE, True, "where the point is in the right image now, row (px; stereo)"),
)
REQUIRED_ARRAYS = ("point_id", "x", "y", "u", "v", "zncc", "ok")
STEREO_ARRAYS = ("x_mm", "y_mm", "z_mm", "u_mm", "v_mm", "w_mm", "stereo_status", "right_x", "right_y")
OPTIONAL_ARRAYS = ("ux", "uy", "vx", "vy", "status", "iterations") + STEREO_ARRAYS
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
    ("l0_mm", 10, _F.TYPE_DOUBLE, False, "reference length L0 in space (mm; stereo sessions, 0 in 2D)"),
    ("l_mm", 11, _F.TYPE_DOUBLE, False, "current length in space (mm; stereo sessions); NaN where not ok"),
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


def schema_data(name: str) -> bytes:
    """Serialized ``FileDescriptorSet`` stored as the MCAP schema ``name`` (encoding "protobuf")."""
    if name == RAW_IMAGE_SCHEMA:
        from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
        from mcap_protobuf.schema import build_file_descriptor_set
        return build_file_descriptor_set(RawImage).SerializeToString()
    if name in (FRAME_RESULTS_SCHEMA, FRAME_INFO_SCHEMA, EVENT_SCHEMA, SESSION_SCHEMA, STRAIN_FIELD_SCHEMA,
                EXTENSOMETER_SAMPLE_SCHEMA, FORCE_SAMPLE_SCHEMA):
        return descriptor_pb2.FileDescriptorSet(file=[FILE_PROTO]).SerializeToString()
    raise KeyError(name)
