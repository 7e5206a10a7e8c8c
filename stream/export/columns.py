"""The columns and files of ``livedic export`` (and of ``livedic replay``'s rows): one frame's long-format
columns, one frame's extensometer rows, and the atomic writer every file goes through.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from livedic.stream.output.files import AtomicFile

if TYPE_CHECKING:
    from livedic.dic.strain.extensometer import ExtensometerReadings


LEADING_COLUMNS = ("frame", "timestamp_ns", "point_id", "x", "y", "u", "v", "zncc", "ok")
EXTRA_COLUMNS = ("status", "ux", "uy", "vx", "vy", "iterations")
P0_COLUMNS = ("frame", "timestamp_ns", "time_s", "x", "y", "u", "v", "zncc", "ok")
EVENT_COLUMNS = ("time", "kind", "level", "message", "timestamp_ns")
STRAIN_COLUMNS = ("exx", "eyy", "exy")
EXTENSOMETER_COLUMNS = ("frame", "time_s", "name", "L0_px", "L_px", "eng_strain", "true_strain", "ok")
# Appended when the session has a scale (--scale, or a calibration's px/mm): lengths, and displacements on the
# specimen plane (undistorted with a calibration), in mm.
EXTENSOMETER_MM_COLUMNS = ("L0_mm", "L_mm")
FIELD_MM_COLUMNS = ("u_mm", "v_mm")
# Appended for a stereo session (fields.csv, replay's rows) instead of FIELD_MM_COLUMNS (a nominal scale's 2D
# displacements, whose names a case-blind reader such as DuckDB would take for U_mm, V_mm): each point in space
# (mm, the left camera's frame), its displacement from the reference pair, its dic.stereo.StereoStatus code.
# Each column's recording array (acquire.recording.schema.STEREO_ARRAYS) is its name in lower case.
STEREO_COLUMNS = ("X_mm", "Y_mm", "Z_mm", "U_mm", "V_mm", "W_mm", "stereo_status")
EXPORT_FILES = ("p0_trace.csv", "fields.csv", "events.csv", "session.json", "extensometers.csv", "extensometers.png")
BINARY_FILES = ("extensometers.png", "stress_strain.png")
STRESS_FILES = ("stress_strain.csv", "stress_strain.png")
EXPORT_KEY = "livedic.export"


def result_columns(frame_index: int, timestamp_ns: int, point_id: np.ndarray, x: np.ndarray, y: np.ndarray,
                   u: np.ndarray, v: np.ndarray, zncc: np.ndarray, ok: np.ndarray,
                   extras: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """The long-format columns of one frame (``LEADING_COLUMNS`` then ``extras`` in ``EXTRA_COLUMNS`` order)."""
    columns: dict[str, Any] = {"frame": int(frame_index), "timestamp_ns": int(timestamp_ns), "point_id": point_id,
               "x": x, "y": y, "u": u, "v": v, "zncc": zncc, "ok": np.asarray(ok, dtype=bool)}
    for name in EXTRA_COLUMNS:
        if name in extras:
            columns[name] = extras[name]
    return columns


def mm_columns(stereo: bool, scaled: bool) -> tuple[str, ...]:
    """The columns in mm after ``STRAIN_COLUMNS``: ``STEREO_COLUMNS`` for a stereo frame, else ``FIELD_MM_COLUMNS``
    with a scale, else none."""
    return STEREO_COLUMNS if stereo else FIELD_MM_COLUMNS if scaled else ()


def stereo_columns(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``STEREO_COLUMNS`` from a stereo frame's arrays named as recorded (``RecordedResults.stereo``,
    ``stream.pipeline.sinks.stereo_arrays``); {} when it has none (2D)."""
    if not arrays:
        return {}
    return {name: np.asarray(arrays[name.lower()]) for name in STEREO_COLUMNS}


# The atomic writer shared by every output of livedic (kept under its old name for callers).
StagedFile = AtomicFile


def extensometer_columns(frame_index: int, time_s: float, readings: ExtensometerReadings,
                         px_per_mm: float | None = None) -> dict[str, Any]:
    """The ``EXTENSOMETER_COLUMNS`` of one frame's ``ExtensometerReadings`` (one row per extensometer), then
    ``EXTENSOMETER_MM_COLUMNS`` with a scale ``px_per_mm``, or the lengths in space of a stereo frame's readings."""
    columns = {"frame": int(frame_index), "time_s": float(time_s),
               "name": np.array([_csv_cell(name) for name in readings.names], dtype=object),
               "L0_px": readings.l0_px, "L_px": readings.length_px, "eng_strain": readings.eng_strain,
               "true_strain": readings.true_strain, "ok": np.asarray(readings.ok, dtype=bool)}
    if readings.l0_mm is not None:               # a stereo frame's: measured in space
        columns.update(L0_mm=np.asarray(readings.l0_mm), L_mm=np.asarray(readings.length_mm))
    elif px_per_mm:
        columns.update(L0_mm=np.asarray(readings.l0_px) / px_per_mm, L_mm=np.asarray(readings.length_px) / px_per_mm)
    return columns


def _csv_cell(text: object) -> str:
    """``text`` as one CSV cell (quoted only where CSV needs it)."""
    cell = str(text)
    if any(c in cell for c in ',"\n\r'):
        return '"' + cell.replace('"', '""') + '"'
    return cell
