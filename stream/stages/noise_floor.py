"""The session's noise floor: the static frames after the reference, measured (``dic.noise_floor``).

A session with ``--static-frames N`` (``stream.session.config``) takes the N frames after the reference (frame
indices reference + 1 .. reference + N: a frame the queue dropped is missing, never replaced by a later,
moving one) while nothing moves (the simulator renders them; a camera's user holds the specimen still). The
``NoiseFloorStage`` (a ``stream.pipeline.stage.Stage``, after the strain stage) keeps those frames' u, v, ok,
strain and extensometer strain (``StaticFrames``) and, after the Nth, computes the noise floor of each
quantity (``dic.noise_floor.field_noise_floor``), sets it on that frame's result (``result.noise_floor``) and
gives it to the summary (``summary_lines``, ``summary``). A session that ends before N gives what it had (NaN
below two frames, with the reason). A stereo session's static pairs (its ``StereoMeasurement``: the left view's
u, v and the 3D points) add U, V, W in mm (the specimen's axes), and its strain and extensometers are those on the
surface and in space: one code path, the 3D points the only difference. ``recorded_noise_floor`` computes the same table from a recording's
results, strain and extensometer readings (the static count is in its metadata: ``static_frames``), for
``livedic report``; ``noise_floor_lines`` formats a table for the summary, the report and
``livedic noise-floor``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from livedic.dic.noise_floor import DISPLACEMENT_3D, NoiseFloor, field_noise_floor
from livedic.dic.stereo import StereoStatus
from livedic.dic.strain.field import StrainStatus
from livedic.stream.pipeline.frame_result import FrameResult
from livedic.stream.pipeline.stage import Reference, Stage
from livedic.stream.stages.strain import StrainConfig

# The metadata key (recording, --summary-json) of the static frames' count, and of the table in a summary.
STATIC_FRAMES_KEY = "static_frames"
NOISE_FLOOR_KEY = "noise_floor"


class StaticFrames:
    """The static frames' values, kept as they come (one frame at a time), and their noise floor.

    Parameters
    ----------
    scale_px_per_mm : float, optional
        Adds u and v in mm to the table.
    stereo : bool
        Static pairs: U, V, W rows, NaN with the reason while no pair is in.
    """

    def __init__(self, scale_px_per_mm: float | None = None, *, stereo: bool = False) -> None:
        self.scale_px_per_mm = scale_px_per_mm
        self.stereo = stereo
        self.frame_indices: list[int] = []
        self._u: list[np.ndarray] = []
        self._v: list[np.ndarray] = []
        self._ok: list[np.ndarray] = []
        self._strain: dict[str, list[np.ndarray]] = {"exx": [], "eyy": [], "exy": []}
        self._strain_ok: list[np.ndarray] = []
        self._extensometers: dict[str, tuple[list[float], list[bool]]] = {}
        self._xyz: list[np.ndarray] = []            # stereo: each pair's 3D points, displacements and status
        self._displacement: list[np.ndarray] = []
        self._ok_3d: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.frame_indices)

    def add(self, frame_index: int, u: np.ndarray, v: np.ndarray, ok: np.ndarray, strain: Any = None,
            extensometers: Any = None, points: Any = None) -> None:
        """One static frame: displacements (px) and ok, its ``StrainField`` (or a recorded strain: ``exx``,
        ``eyy``, ``exy`` and ``status``), its ``ExtensometerReadings`` (None: none) and, of a stereo pair, its 3D
        points (``dic.stereo.StereoPoints``, or any object with ``xyz``, ``displacement`` and ``ok``)."""
        self.frame_indices.append(int(frame_index))
        if points is not None:
            self._xyz.append(np.array(points.xyz, dtype=np.float64))
            self._displacement.append(np.array(points.displacement, dtype=np.float64))
            self._ok_3d.append(np.array(points.ok, dtype=bool))
        self._u.append(np.array(u, dtype=np.float64))
        self._v.append(np.array(v, dtype=np.float64))
        self._ok.append(np.array(ok, dtype=bool))
        if strain is not None:
            for name, values in self._strain.items():
                values.append(np.array(getattr(strain, name), dtype=np.float64))
            self._strain_ok.append(np.asarray(strain.status) == int(StrainStatus.OK))
        if extensometers is not None:
            for name, strain_value, good in zip(extensometers.names, extensometers.eng_strain, extensometers.ok):
                series = self._extensometers.setdefault(name, ([], []))
                series[0].append(float(strain_value))
                series[1].append(bool(good))

    def table(self) -> list[NoiseFloor]:
        """The noise floor of every quantity (``dic.noise_floor.field_noise_floor``) over the frames so far."""
        frames = len(self)
        width = len(self._u[0]) if frames else 0
        u = np.array(self._u) if frames else np.zeros((0, width))
        v = np.array(self._v) if frames else np.zeros((0, width))
        ok = np.array(self._ok) if frames else np.zeros((0, width), bool)
        with_strain = frames > 0 and len(self._strain_ok) == frames
        strain = {name: np.array(values) for name, values in self._strain.items()} if with_strain else {}
        extensometers = {name: (np.array(values), np.array(good)) for name, (values, good)
                         in self._extensometers.items() if len(values) == frames}
        stereo = {}
        if self.stereo or self._displacement:               # the pairs' 3D points (none yet: the rows say so)
            shape = (len(self._displacement), width, 3)
            stereo = {"xyz_mm": np.array(self._xyz).reshape(shape),
                      "displacement_mm": np.array(self._displacement).reshape(shape),
                      "ok_3d": np.array(self._ok_3d, dtype=bool).reshape(shape[:2])}
        return field_noise_floor(u, v, ok, **strain, strain_ok=np.array(self._strain_ok) if with_strain else None,
                                 extensometers=extensometers, scale_px_per_mm=self.scale_px_per_mm, **stereo)


class NoiseFloorStage(Stage):
    """Keeps the first ``static_frames`` frames after the reference and measures their noise floor.

    Parameters
    ----------
    static_frames : int
        Frames after the reference in which nothing moves (>= 1; a session without them has no such stage).
    scale_px_per_mm : float, optional
        The strain configuration's scale (u and v in mm too; a stereo session has U, V, W in mm instead).
    stereo : bool
        A stereo session's static pairs (``StaticFrames``).

    Attributes
    ----------
    table : list of dic.noise_floor.NoiseFloor or None
        The noise floor, once the static frames are in (or the session ended).
    """
    name = "noise floor"
    needs: ClassVar[tuple[str, ...]] = ("measurement", "strain", "extensometers")
    provides: ClassVar[tuple[str, ...]] = ("noise_floor",)
    required = False

    def __init__(self, static_frames: int, scale_px_per_mm: float | None = None, *, stereo: bool = False) -> None:
        self.static_frames = int(static_frames)
        self._last = self.static_frames         # the last static frame's index (set on the reference)
        self.frames = StaticFrames(scale_px_per_mm, stereo=stereo)
        self.table: list[NoiseFloor] | None = None

    def on_reference(self, reference: Reference) -> None:
        self.frames = StaticFrames(self.frames.scale_px_per_mm, stereo=self.frames.stereo)
        self.table = None
        self._last = reference.frame_index + self.static_frames     # the last static frame's index

    def on_frame(self, result: FrameResult) -> None:
        if result.is_reference or self.table is not None:
            return
        index = result.frame.index
        if not self.frames.frame_indices and index > self._last and not result.dropped_since_last:
            # A camera streams on while the session is prepared: its frames after the reference were never
            # delivered (no queue dropped them), so the still specimen's window starts at the first one that was.
            self._last = index + self.static_frames - 1
        if index <= self._last:
            m = result.measurement
            self.frames.add(index, m.u, m.v, m.ok, result.strain, result.extensometers,
                            getattr(m, "points", None))     # a stereo pair's 3D points (StereoMeasurement)
        if index >= self._last:                 # the last static frame, or past it (it was dropped)
            self.table = self.frames.table()
            result.noise_floor = self.table

    def final_table(self) -> list[NoiseFloor]:
        """The table, or what the frames so far give (a session shorter than its static frames)."""
        return self.table if self.table is not None else self.frames.table()

    def metadata(self) -> dict[str, Any]:
        return {STATIC_FRAMES_KEY: self.static_frames}

    def summary(self) -> dict[str, Any]:
        """``{"static_frames": N, "frames_used": n, "table": [NoiseFloor.as_dict(), ...]}``."""
        return noise_floor_summary(self.static_frames, self.frames.frame_indices, self.final_table())

    def summary_lines(self) -> list[str]:
        return noise_floor_lines(self.summary())


def noise_floor_summary(static_frames: int, frame_indices: Sequence[int], table: Iterable[NoiseFloor]
                        ) -> dict[str, Any]:
    """The noise floor as a summary, the recording's report and ``livedic noise-floor -o`` write it (JSON-ready)."""
    return {STATIC_FRAMES_KEY: int(static_frames), "frames_used": list(frame_indices),
            "table": [floor.as_dict() for floor in table]}


def _number(value: float | None, digits: int) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


_DIGITS = {"px": 4, "mm": 5, "microstrain": 1}


def noise_floor_rows(summary: Mapping[str, Any]) -> list[list[str]]:
    """The table's rows as text: quantity, unit, spatial SD, temporal SD mean and max, mean, points, note."""
    rows = []
    for item in summary["table"]:
        digits = _DIGITS.get(item["unit"], 4)
        note = "" if item["status"] == "ok" else item["reason"]
        rows.append([item["quantity"], item["unit"], _number(item["spatial_sd"], digits),
                     _number(item["temporal_sd_mean"], digits), _number(item["temporal_sd_max"], digits),
                     _number(item["mean"], digits), str(item["points"]), note])
    return rows


NOISE_FLOOR_COLUMNS = ("quantity", "unit", "spatial SD", "temporal SD (mean)", "temporal SD (max)", "mean (bias)",
                       "points", "note")


def noise_floor_lines(summary: Mapping[str, Any], *, indent: str = "  ") -> list[str]:
    """The summary's lines: a header saying on how many static frames, then one aligned line per quantity."""
    used = len(summary["frames_used"])
    stereo = any(item["quantity"] in DISPLACEMENT_3D for item in summary["table"])
    frames = "pair(s)" if stereo else "frame(s)"
    lines = [f"{indent}{'noise':<11}floor on {used} static {frames} after the reference"
             + (f" (of {summary[STATIC_FRAMES_KEY]} asked)" if used < summary[STATIC_FRAMES_KEY] else "")
             + f"; SD over points (spatial), over {'pairs' if stereo else 'frames'} per point (temporal)"]
    if stereo:
        lines.append(f"{indent}{'':<11}stereo: u, v the left view (px); U, V, W in space in the specimen's axes "
                     f"(W along its normal; X, Y, Z have their temporal SD); strain on its surface, extensometers "
                     f"in space")
    rows = [list(NOISE_FLOOR_COLUMNS)] + noise_floor_rows(summary)
    widths = [max(len(row[i]) for row in rows) for i in range(len(NOISE_FLOOR_COLUMNS) - 1)]
    for row in rows:
        cells = [cell.rjust(width) if i > 1 else cell.ljust(width) for i, (cell, width) in
                 enumerate(zip(row, widths))]
        lines.append((f"{indent}{'':<11}" + "  ".join(cells) + (f"  {row[-1]}" if row[-1] else "")).rstrip())
    return lines


def recorded_noise_floor(recording: Any, metadata: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The noise floor of a recording's static frames (``noise_floor_summary``), or None without any.

    Parameters
    ----------
    recording : acquire.recording.reader.RecordingReader
        Opened; its results, strain and extensometer readings are read for the first frames only.
    metadata : dict, optional
        Its session metadata (default: read from it).
    """
    metadata = metadata if metadata is not None else recording.session()
    static = int(metadata.get(STATIC_FRAMES_KEY) or 0)
    if static <= 0:
        return None
    scale = StrainConfig.from_metadata(metadata).px_per_mm     # --scale, else the calibration's, as live
    frames: dict[int, Any] = {}
    reference = last = None
    for record in recording.results():
        if reference is None:                  # the first results: the reference
            reference, last = record.frame_index, record.frame_index + static
            frames[record.frame_index] = record
            continue
        if len(frames) == 1 and record.frame_index > last and not record.dropped_frames:
            last = record.frame_index + static - 1     # a camera's frames never delivered: as NoiseFloorStage does
        if record.frame_index > last:
            break
        frames[record.frame_index] = record
    indices = sorted(frames)[1:]
    strains = _first(recording.strain_fields(), indices, lambda s: s.frame_index)
    readings = _first(recording.extensometer_readings(), indices, lambda r: r[0])
    stereo = bool(reference is not None and frames[reference].stereo)     # its 3D points are on /dic/results
    kept = StaticFrames(None if stereo else float(scale) if scale else None, stereo=stereo)
    for index in indices:
        m = frames[index].measurement
        reading = readings.get(index)
        kept.add(index, m.u, m.v, m.ok, strains.get(index), reading[2] if reading is not None else None,
                 RecordedPoints.of(frames[index].stereo) if stereo else None)
    return noise_floor_summary(static, indices, kept.table())


@dataclass(frozen=True)
class RecordedPoints:
    """A recorded stereo frame's 3D points as ``StaticFrames.add`` reads them (``StereoPoints``' names)."""
    xyz: np.ndarray
    displacement: np.ndarray
    ok: np.ndarray

    @classmethod
    def of(cls, stereo: Mapping[str, np.ndarray]) -> RecordedPoints:
        """From a ``RecordedResults.stereo`` (``x_mm`` .. ``w_mm``, ``stereo_status``: 0 is ok)."""
        return cls(np.column_stack([stereo[name] for name in ("x_mm", "y_mm", "z_mm")]),
                   np.column_stack([stereo[name] for name in ("u_mm", "v_mm", "w_mm")]),
                   np.asarray(stereo["stereo_status"]) == int(StereoStatus.OK))


def _first(items: Iterable[Any], indices: Sequence[int], index_of: Any) -> dict[int, Any]:
    """``{frame index: item}`` for the items of ``indices``, reading no further than the last of them."""
    wanted, out = set(indices), {}
    last = max(indices) if indices else -1
    for item in items:
        index = index_of(item)
        if index in wanted:
            out[index] = item
        if index >= last:
            break
    return out
