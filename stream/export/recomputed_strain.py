"""The strain of a recording recomputed from its recorded displacements, as the live session computed it.

The recorded settings (``stream.stages.strain.StrainConfig.from_metadata``) place the same ``StrainStage``
on the recorded reference points (P0 first); ``axial_series`` reads the ``axial`` extensometer frame by frame
(``livedic report``), ``plot_extensometers`` draws ``extensometers.png``.

A stereo recording's strain is not recomputed: its surface strain (``/dic/strain``) and extensometers in space
(``/dic/extensometers``) are read as recorded (``StereoStrainRecord``). They are the live measurement itself, bit for
bit what the session showed and the report reads; recomputing them from the recorded 3D points would run the same
dic.stereo code on the same numbers, and a measurement with other settings is ``livedic replay``'s (it re-runs the
3D measurement from both views' frames).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from typing import IO, TYPE_CHECKING, Any, Iterable, Iterator, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from livedic.stream.export.notes import reader_notes, session_or_note

if TYPE_CHECKING:
    from livedic.acquire.recording.reader import Recording
    from livedic.acquire.recording.records import RecordedResults
    from livedic.dic.calibration import StereoCalibration
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.stream.stages.strain import StrainConfig, StrainStage


def p0_point_id(metadata: Mapping[str, Any]) -> tuple[int, str]:
    """(id of the traced point P0, how it was found) from session metadata; 0 by convention."""
    for key in ("p0_id", "p0_point_id"):
        value = metadata.get(key)
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0:
            return int(value), f"session metadata {key}"
    text = metadata.get("point_ids")
    if isinstance(text, str):
        match = re.search(r"P0 is point (\d+)", text)
        if match:
            return int(match.group(1)), f"session metadata point_ids ({text!r})"
    return 0, "not in the session metadata: point 0, livedic's convention"


def reference_geometry(metadata: Mapping[str, Any], first: RecordedResults,
                       p0_id: int) -> tuple[np.ndarray, tuple[float, ...], tuple[float, ...], float | None, int]:
    """(points (N, 2), p0 (x, y), roi, step, subset) of a recording, as the session placed its strain stage.

    ``first`` is the first ``RecordedResults``: its ``x, y`` are the reference points as the
    tracker used them (pixel centres), P0 the point ``p0_id`` (point 0 by convention). The
    ROI is the recorded one, or the points' extent when the session had none ("full image");
    the step the recorded grid step (None: the points' typical spacing).
    """
    points = np.column_stack([first.x, first.y]).astype(np.float64)
    where = np.flatnonzero(first.point_id == p0_id)
    p0 = tuple(points[int(where[0]) if where.size else 0])
    roi = metadata.get("roi")
    if isinstance(roi, (list, tuple)) and len(roi) == 4 and all(isinstance(v, (int, float)) for v in roi):
        roi = tuple(float(v) for v in roi)
    elif len(points):
        lo, hi = points.min(axis=0), points.max(axis=0)
        roi = (lo[0], lo[1], hi[0] - lo[0], hi[1] - lo[1])
    else:
        roi = (0.0, 0.0, 0.0, 0.0)
    step = None
    for key in ("grid_step", "step"):
        value = metadata.get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
            step = float(value)
            break
    subset = metadata.get("subset")
    subset = int(subset) if isinstance(subset, int) and not isinstance(subset, bool) and subset > 0 else 21
    return points, p0, roi, step, subset


def strain_stage(metadata: Mapping[str, Any], first: RecordedResults, p0_id: int,
                 config: StrainConfig) -> StrainStage:
    """The ``stream.stages.strain.StrainStage`` of a recording, ``config`` placed on its reference points (a stereo
    recording's: the ``StereoStrainStage``, placed as live).

    Raises
    ------
    ValueError
        A bad setting, or an extensometer end away from the tracked points (one line).
    """
    points, p0, roi, step, subset = reference_geometry(metadata, first, p0_id)
    stage = config.place(points, p0=p0, roi=roi, step=step, subset=subset)
    if recorded_rig(metadata) is not None:
        from livedic.stream.stages.stereo_strain import StereoStrainStage
        return StereoStrainStage.of(stage)
    return stage


def recorded_rig(metadata: Mapping[str, Any]) -> StereoCalibration | None:
    """A stereo recording's rig (its session metadata's ``stereo``), None for one camera."""
    from livedic.dic.calibration import StereoCalibration
    from livedic.stream.session.stereo import STEREO_KEY
    stereo = metadata.get(STEREO_KEY)
    return StereoCalibration.from_dict(stereo["calibration"]) if isinstance(stereo, Mapping) else None


def recorded_strain_config(metadata: Mapping[str, Any], overrides: Mapping[str, Any] | None) -> StrainConfig:
    """The strain settings of a recording (``overrides`` replacing them); a stereo recording's as its session had them
    (the rig's nominal scale, the surface measure), which take no overrides: its strain and extensometers are the
    recorded ones.

    Raises
    ------
    ValueError
        A bad setting; a strain option given for a stereo recording (one line).
    """
    from livedic.stream.stages.stereo_strain import stereo_strain_config
    from livedic.stream.stages.strain import StrainConfig
    rig = recorded_rig(metadata)
    if rig is None:
        return StrainConfig.from_metadata(metadata, **(overrides or {}))
    if overrides:
        raise ValueError(f"a stereo recording's strain and extensometers are taken as its session measured them (on "
                         f"the specimen's surface, in space): {', '.join(sorted(overrides))} cannot change them here; "
                         f"livedic replay FILE.mcap -o ROWS.csv with those options measures it again in 3D")
    return stereo_strain_config(StrainConfig.from_metadata(metadata), rig)


class _FrameCursor:
    """Items of a recorded topic in frame order, taken by frame index alongside ``/dic/results``: the item of that
    frame, or None when the topic has none for it (items of frames passed by are skipped)."""

    def __init__(self, items: Iterator[Any], frame_of: Any) -> None:
        self._items = items
        self._frame_of = frame_of
        self._ahead: Any = None

    def take(self, frame_index: int) -> Any:
        while True:
            if self._ahead is None:
                self._ahead = next(self._items, None)
                if self._ahead is None:
                    return None
            frame = self._frame_of(self._ahead)
            if frame > frame_index:
                return None
            item, self._ahead = self._ahead, None
            if frame == frame_index:
                return item


class StereoStrainRecord:
    """A stereo recording's strain as its session measured it, frame by frame: the surface strain recorded on
    ``/dic/strain`` and the extensometers in space on ``/dic/extensometers`` (``l0_mm``, ``length_mm``; engineering
    strain = L / L0 - 1), read alongside its results."""

    def __init__(self, recording: Recording, names: Sequence[str]) -> None:
        self.names = tuple(names)
        self._strain = _FrameCursor(recording.strain_fields(), lambda field: int(field.frame_index))
        self._readings = _FrameCursor(recording.extensometer_readings(), lambda item: int(item[0]))

    def at(self, result: RecordedResults, placed: Any) -> tuple[Any, ExtensometerReadings]:
        """(strain field with ``exx, eyy, exy``, extensometer readings) recorded for ``result``'s frame; NaN strain
        and lost readings (``placed``: the extensometers) where the frame has none recorded or other points."""
        field = self._strain.take(int(result.frame_index))
        item = self._readings.take(int(result.frame_index))
        if field is None or not np.array_equal(field.point_id, result.point_id):
            field = _no_strain(len(result.u))
        readings = item[2] if item is not None and item[2].names == self.names else _lost_readings(placed)
        return field, readings


@dataclass(frozen=True)
class _NoStrain:
    exx: np.ndarray
    eyy: np.ndarray
    exy: np.ndarray


def _no_strain(n: int) -> _NoStrain:
    return _NoStrain(np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan))


def _lost_readings(placed: Any) -> ExtensometerReadings:
    """Readings of ``placed`` extensometers for a frame whose points differ from the reference's: none ok."""
    from livedic.dic.strain.extensometer import ExtensometerReadings, ExtensometerStatus
    n = len(placed.names)
    nan = np.full(n, np.nan)
    l0 = np.array([e.length_px for e in placed.extensometers], dtype=np.float64)
    return ExtensometerReadings(names=placed.names, l0_px=l0, length_px=nan, eng_strain=nan.copy(),
                                true_strain=nan.copy(),
                                status=np.full(n, int(ExtensometerStatus.END_LOST), dtype=np.int32))


def plot_extensometers(handle: IO[bytes], times: npt.ArrayLike, names: Sequence[str], l0_px: Sequence[float],
                       strains: npt.ArrayLike, *, title: str, scale: float | None = None, empty_note: str = "",
                       l0_mm: Sequence[float] | None = None) -> None:
    """Write ``extensometers.png`` to ``handle``: engineering strain (%) against time, one line each.

    ``strains`` is (frames, extensometers), NaN where not ok: the line has a gap there
    (points drawn too, so a reading between two gaps still shows). ``l0_px`` may be shorter than
    ``names`` (a recording with no results places no extensometer): those have no L0 in the legend.
    ``l0_mm``: a stereo recording's L0s measured in space, in the legend instead.
    """
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 4.5), dpi=100, layout="constrained")
    axes = figure.add_subplot()
    times = np.asarray(times, dtype=np.float64)
    strains = np.asarray(strains, dtype=np.float64).reshape(len(times), len(names))
    for k, name in enumerate(names):
        if l0_mm is not None and k < len(l0_mm):
            name += f" (L0 {l0_mm[k]:.3f} mm in space)"
        elif k < len(l0_px):
            name += f" (L0 {l0_px[k]:.0f} px" + (f" = {l0_px[k] / scale:.2f} mm)" if scale else ")")
        axes.plot(times, 100.0 * strains[:, k], marker=".", markersize=3, linewidth=1.2, label=name)
    axes.set_xlabel("time since the reference frame (s)")
    axes.set_ylabel("engineering strain (L - L0) / L0 (%)")
    axes.set_title(title, fontsize=10)
    axes.grid(True, alpha=0.3)
    axes.axhline(0.0, color="0.5", linewidth=0.6)
    if names:
        gaps = "gaps: no reading (an end lost its points)" if np.isnan(strains).any() else None
        axes.legend(loc="best", fontsize=9, title=gaps, title_fontsize=8)
    else:
        axes.text(0.5, 0.5, empty_note, ha="center", va="center", transform=axes.transAxes, fontsize=10)
    if len(times) == 0 or not names:
        axes.set_xlim(0, 1)
    figure.savefig(handle, format="png")


@dataclass
class RecordedStrain:
    """A recording opened with its strain stage placed as recorded (or with the given overrides), before any
    frame but the first is read: what ``export_recording`` and ``axial_series`` both start from."""
    recording: Recording
    metadata: dict[str, Any]
    p0_id: int
    p0_how: str
    config: StrainConfig
    first: RecordedResults | None
    results: Iterator[RecordedResults]               # the results after ``first``
    stage: StrainStage | None                         # None: no results
    names: tuple[str, ...]                           # the extensometers
    stereo: StereoStrainRecord | None                # a stereo recording's strain as recorded (None: 2D)

    def frame_strain(self, result: RecordedResults) -> tuple[Any | None, ExtensometerReadings]:
        """(strain field or None, extensometer readings) of ``result``'s frame (after ``first``, in order): a stereo
        recording's as recorded, a 2D one's recomputed from its displacements; None and lost readings for a 2D frame
        tracking other points than the first."""
        stage, first = self.stage, self.first
        assert stage is not None and first is not None     # a frame with results: the stage was placed on the first
        if self.stereo is not None:
            return self.stereo.at(result, stage.placed)
        if np.array_equal(result.point_id, first.point_id):
            return stage.compute(result.u, result.v, result.ok)
        return None, _lost_readings(stage.placed)


def open_recorded_strain(path: str | os.PathLike[str], strain: Mapping[str, Any] | None,
                         notes: list[str]) -> RecordedStrain:
    """Open the recording at ``path``, read its first results and place the strain stage on them; a note about
    the session metadata goes to ``notes``. ValueError (one line) for a bad file or strain setting."""
    from livedic.acquire.recording.reader import Recording
    recording = Recording(os.fspath(path))
    metadata, session_note = session_or_note(recording)
    if session_note:
        notes.append(session_note)
    p0_id, p0_how = p0_point_id(metadata)
    config = recorded_strain_config(metadata, strain)
    results = recording.results()
    first = next(results, None)
    stage = strain_stage(metadata, first, p0_id, config) if first is not None else None
    placed: Any = stage.placed if stage is not None else None     # a PlacedExtensometers
    names = placed.names if stage is not None else tuple(e.name for e in config.extensometers)
    stereo = StereoStrainRecord(recording, names) if recorded_rig(metadata) is not None else None
    return RecordedStrain(recording, metadata, p0_id, p0_how, config, first, results, stage, names, stereo)


def axial_series(path: str | os.PathLike[str], strain: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The ``axial`` extensometer of a recording, frame by frame, as ``export_recording`` reads it (recomputed from a 2D
    recording's displacements; a stereo recording's recorded in space, L / L0 - 1 in mm).

    Returns
    -------
    dict
        ``metadata``, ``frames`` (indices), ``time_s`` (since the first frame with results),
        ``eng_strain`` (NaN where not read), ``transverse_eng_strain`` (the ``transverse``
        extensometer's, all NaN without one: ``has_transverse``), ``l0_px``, ``scale`` (px/mm or None), ``stereo``
        (a stereo recording: the strain is the extensometer's in space, as recorded) with ``l0_mm_in_space`` (its L0
        measured in space; NaN in 2D), ``truncated``,
        ``notes``, ``strain`` (the stage's one-line description).

    Raises
    ------
    ValueError
        Not a recording, a bad strain setting, or no ``axial`` extensometer (one line).
    """
    from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE
    with reader_notes() as notes:
        opened = open_recorded_strain(path, strain, notes)
        metadata, config, first, results, stage, names = (opened.metadata, opened.config, opened.first,
                                                          opened.results, opened.stage, opened.names)
        if AXIAL not in names:
            raise ValueError(f"the stress-strain curve needs an '{AXIAL}' extensometer, and this recording has "
                             f"{'only ' + ', '.join(names) if names else 'none'}: add --gauge-length L[,W] "
                             f"(or --extensometer {AXIAL}=x1,y1,x2,y2)")
        column = list(names).index(AXIAL)
        across = list(names).index(TRANSVERSE) if TRANSVERSE in names else None
        frames: list[int] = []
        times: list[float] = []
        eng: list[float] = []
        transverse: list[float] = []
        l0_mm = math.nan                              # a stereo recording's L0 in space
        t0 = None
        for result in _chain(first, results):
            _, readings = opened.frame_strain(result)
            if readings.l0_mm is not None and not math.isfinite(l0_mm):
                l0_mm = float(readings.l0_mm[column])
            t0 = int(result.timestamp_ns) if t0 is None else t0
            frames.append(int(result.frame_index))
            times.append((int(result.timestamp_ns) - t0) / 1e9)
            eng.append(float(readings.eng_strain[column]))
            transverse.append(float(readings.eng_strain[across]) if across is not None else math.nan)
        truncated = opened.recording.info.truncated
    l0 = stage.extensometers[column].length_px if stage is not None else math.nan
    return {"metadata": metadata, "frames": np.asarray(frames, dtype=np.int64),
            "time_s": np.asarray(times, dtype=np.float64), "eng_strain": np.asarray(eng, dtype=np.float64),
            "transverse_eng_strain": np.asarray(transverse, dtype=np.float64), "has_transverse": across is not None,
            "l0_px": float(l0), "l0_mm_in_space": l0_mm, "stereo": opened.stereo is not None,
            "scale": config.px_per_mm, "truncated": truncated, "notes": list(notes),
            "strain": stage.describe() if stage is not None else ""}


def _chain(first: RecordedResults | None, rest: Iterable[RecordedResults]) -> Iterator[RecordedResults]:
    """``first`` (when not None) then the rest of the results."""
    if first is None:
        return
    yield first
    yield from rest


def _strain_settings(stage: StrainStage | None, config: StrainConfig,
                     overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """What the strain columns and the extensometers were computed with, for ``session.json`` (a stereo stage's:
    not recomputed, ``recomputed_from`` None and ``as_recorded`` saying what)."""
    from livedic.stream.stages.stereo_strain import StereoStrainStage
    stereo = isinstance(stage, StereoStrainStage)
    settings: dict[str, Any] = {"recomputed_from": None if stereo else "the recorded displacements",
                                "measure": config.measure,
                                "window": config.window, "scale_px_per_mm": config.px_per_mm,
                                "overridden": sorted(overrides or {})}
    if stage is not None:
        windows: Any = stage.windows                  # a dic.strain.field.StrainWindows
        settings.update(step_px=windows.step, subset_px=windows.subset, vsg_px=stage.vsg_px,
                        extensometers=[{"name": e.name, "x1": e.x1, "y1": e.y1, "x2": e.x2, "y2": e.y2,
                                        "L0_px": e.length_px} for e in stage.extensometers])
    if stereo:
        settings["as_recorded"] = ("the stereo session's strain on the specimen's surface (/dic/strain) and "
                                   "extensometers in space (/dic/extensometers)")
    return settings
