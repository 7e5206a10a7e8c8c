"""``livedic export``: a recording's results as CSV files anyone can open.

``livedic export FILE.mcap -o DIR`` writes into DIR (created if missing) ``p0_trace.csv``,
``fields.csv`` (the columns of ``livedic replay``, then ``exx,eyy,exy``),
``extensometers.csv``, ``extensometers.png``, ``events.csv``, ``session.json``, and, with a
force (``--load csv:FILE`` or one recorded on ``/machine/force``), ``stress_strain.csv`` and
``stress_strain.png``; their columns are in ``columns`` and docs/guide/export.md ("The CSV
files"). Then the fields as pictures (``stream.export.field_export``): maps, a video, VTK.

Strain and extensometers are *recomputed* from the recorded displacements with the settings
the recording was made with (``StrainConfig.from_metadata``), by the same ``StrainStage`` as
the live session; ``--strain-window --strain-measure --gauge-length --extensometer --scale``
replace them. A stereo recording's are its session's as recorded (the strain on the specimen's surface,
the extensometers in space: ``recomputed_strain.StereoStrainRecord``), and take no such option.

Guarantees: numbers at full precision (a value read back is bit-for-bit the recorded one),
NaN as ``nan``, ``ok`` as 1/0; the CSV files are written under temporary names and renamed
into place only when all are complete, so an error or Ctrl-C never leaves a half-written
file; Ctrl-C or SIGTERM (``StopSignals``) stops at the next frame, keeps what is whole and
says so (exit 130 or 143); existing files are kept unless ``--overwrite``; a truncated
recording exports what can be recovered, flagged by ``RecordingInfo.truncated``.

The parts live beside this module: ``columns`` (the CSV columns and files), ``notes`` (the
reader's notes, the session metadata), ``recomputed_strain``, ``force`` (the machine's force
and the stress-strain files), ``stop`` (Ctrl-C and SIGTERM); ``livedic replay`` uses the
first two.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, Callable, Sequence

import numpy as np

from livedic.acquire.atomic_file import atomic_files
from livedic.stream.output.files import check_output_folder, json_text, write_text_atomic
from livedic.stream.output.csv_text import csv_rows, scalar_text
from livedic.stream.export.field_maps import COLOUR_MAP
from livedic.stream.export.field_options import NO_FIELDS, PVD_FILE, VIDEO_FOURCC, ColourRanges, quantities, video_name
from livedic.stream.export.field_writer import FieldWriter, RecordedImages, remove_stale
from livedic.stream.export.columns import (BINARY_FILES, EVENT_COLUMNS, EXPORT_FILES, EXPORT_KEY, EXTENSOMETER_COLUMNS,
                                          EXTENSOMETER_MM_COLUMNS, EXTRA_COLUMNS, FIELD_MM_COLUMNS, LEADING_COLUMNS,
                                          P0_COLUMNS, STEREO_COLUMNS, STRAIN_COLUMNS, STRESS_FILES,
                                          extensometer_columns, mm_columns, result_columns, stereo_columns)
from livedic.stream.export.force import RecordedForce, _force_label, _open_stress_load, _write_stress_strain
from livedic.stream.export.notes import plural, reader_notes
from livedic.stream.export.recomputed_strain import (RecordedStrain, StereoStrainRecord, _chain, _strain_settings,
                                                     open_recorded_strain, plot_extensometers, recorded_rig)
from livedic.stream.export.stop import _stopped_in
# Re-exported: stream.cli's export, replay and report commands name them as export's.

if TYPE_CHECKING:
    from livedic.acquire.atomic_file import AtomicFile
    from livedic.acquire.force import LoadSource
    from livedic.acquire.recording.records import RecordedEvent, RecordedResults
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.stream.export.field_options import FieldOptions, Quantity
    from livedic.stream.pipeline.progress import ProgressBar
    from livedic.stream.stages.stress import StressOptions


def export_recording(path: str | os.PathLike[str], directory: str | os.PathLike[str], *, overwrite: bool = False,
                     strain: dict[str, Any] | None = None, stress: StressOptions | None = None,
                     fields: FieldOptions = NO_FIELDS, stop: Callable[[], None] | None = None,
                     progress: ProgressBar | None = None) -> dict[str, Any]:
    """Write ``EXPORT_FILES`` for recording ``path`` into ``directory`` (see module notes).

    The CSV files, plots and ``session.json`` are written first, together (all or none); then, with
    ``fields``, the maps, video and VTK files (``stream.export.field_export``), each file whole, and
    ``session.json`` again with what they are.

    Parameters
    ----------
    path, directory : str or os.PathLike
    overwrite : bool
    strain : dict, optional
        Strain settings replacing the recorded ones (``stream.stages.strain.overrides_from_args``).
    stress : stream.stages.stress.StressOptions, optional
        Force file and cross-section: also write ``STRESS_FILES``.
    fields : stream.export.field_export.FieldOptions
        The maps, video and VTK to write (default none).
    stop : callable, optional
        Called once per frame; raises ``ExportStopped`` to end the export there (``StopSignals.check``).
    progress : stream.pipeline.progress.ProgressBar, optional

    Returns
    -------
    dict
        ``directory``, ``files`` (paths), ``frames`` (frames with results),
        ``points`` (points in the first frame), ``events``, ``p0_id``, ``p0_rows``,
        ``truncated``, ``notes`` (list of lines), ``extensometers`` (names),
        ``strain`` (one line: window, VSG, measure, extensometers; "" without results),
        ``stress`` (None, or ``frames_with_force`` and ``uniform_frame``, the frame of maximum force or -1),
        ``fields`` (None, or a ``stream.export.field_export.FieldReport``).

    Raises
    ------
    ExportStopped
        ``stop`` raised it; its ``state`` says what the folder holds.
    ValueError
        ``directory`` is a file, a target exists without ``overwrite``, a strain setting is
        bad or an extensometer lies off the points, or the recording is missing, not MCAP,
        not livedic, or corrupt (``RecordingError``).
    """
    path, directory = os.fspath(path), os.fspath(directory)
    outputs = EXPORT_FILES + (STRESS_FILES if stress is not None else ())
    targets = _check_targets(directory, outputs, fields, overwrite)
    stop = stop or (lambda: None)
    with reader_notes() as notes:
        source = _read_source(path, strain, stress, fields, notes)      # every check before DIR is made
        created = not os.path.isdir(directory)
        with _stopped_in(f"while writing the CSV files: nothing was written"
                         f"{f' ({directory} removed again)' if created else ''}"), \
                atomic_files(targets, binary=BINARY_FILES) as staged:
            written = _write_frame_files(staged, source, stop, progress)
            events = source.recording.events()
            if written.t0 is None and events:
                written.t0 = min(event.timestamp_ns for event in events)
            staged["events.csv"].write(_events_csv(events, written.t0))
            notes.extend(_frame_notes(path, source, written))
            _plot_extensometer_file(staged, path, source, written)
            stress_summary = _stress_strain_files(staged, path, source, written, stress)
            session = _session_json(path, source, written, events, notes, strain, stress, stress_summary)
            staged["session.json"].write(json_text(session))
        report = None
        if fields.wanted and written.frames:
            report = _write_fields(path, directory, fields, source.shown, source.ranges, source.stage, source.first,
                                   written.frames, written.t0, overwrite, stop, progress,
                                   title_note=os.path.basename(path), in_space=source.stereo is not None)
            session[EXPORT_KEY]["fields"] = _fields_settings(fields, source.shown, source.ranges, report, source.stage)
            write_text_atomic(targets["session.json"], json_text(session))
            notes.extend(_field_notes(report))
        elif fields.wanted:
            notes.append("no tracking results: no maps, video or VTK files")
    stage = source.stage
    return {"directory": directory, "files": [targets[name] for name in outputs], "frames": written.frames,
            "points": written.points, "events": len(events), "p0_id": source.p0_id, "p0_rows": written.p0_rows,
            "truncated": session[EXPORT_KEY]["truncated"], "notes": list(notes), "extensometers": list(source.names),
            "strain": stage.describe() if stage is not None else "", "stress": stress_summary, "fields": report}


def _check_targets(directory: str, outputs: tuple[str, ...], fields: FieldOptions, overwrite: bool) -> dict[str, str]:
    """The path of each of ``outputs`` in ``directory``; ValueError (one line) where one exists, without
    ``overwrite``."""
    check_output_folder(directory, "-o")
    targets = {name: os.path.join(directory, name) for name in outputs}
    existing = [name for name, target in targets.items() if os.path.lexists(target)] + fields.existing(directory)
    if existing and not overwrite:
        raise ValueError(f"{directory} already holds {', '.join(existing)}: pass --overwrite to replace "
                         f"{'it' if len(existing) == 1 else 'them'}, or choose another folder")
    return targets


@dataclass
class _Source(RecordedStrain):
    """What the export reads of the recording before it writes anything: the recording with its strain stage
    (``RecordedStrain``), and the force and colour ranges."""
    load: LoadSource | RecordedForce | None
    shown: dict[str, Quantity]
    ranges: ColourRanges


def _read_source(path: str, strain: dict[str, Any] | None, stress: StressOptions | None, fields: FieldOptions,
                 notes: list[str]) -> _Source:
    """Open the recording and set up what the export needs: a bad file, setting or load raises here, before
    the output folder is made."""
    opened = open_recorded_strain(path, strain, notes)
    config, stage = opened.config, opened.stage
    load = _open_stress_load(stress, opened.names, opened.recording)      # bad load or no axial extensometer
    shown = quantities(config.px_per_mm, fields.strain_unit, config.measure, stage.vsg_px if stage is not None else None)
    ranges = ColourRanges(shown, fields.ranges, fields.coloured)
    return _Source(**vars(opened), load=load, shown=shown, ranges=ranges)


@dataclass
class _Written:
    """What the pass over the results wrote: counts, the time origin, and each frame's extensometer strain."""
    frames: int = 0
    points: int = 0                                  # in the first frame
    p0_rows: int = 0
    p0_missing: int = 0
    other_points: int = 0                            # frames tracking other points than the first
    t0: int | None = None                            # ns: the first frame's timestamp (time_s = 0)
    times: list[float] = field(default_factory=list)
    frame_numbers: list[int] = field(default_factory=list)
    eng: list[np.ndarray] = field(default_factory=list)
    l0_mm: list[float] | None = None                 # a stereo recording's L0s measured in space

    def eng_strain(self, names: Sequence[str]) -> np.ndarray:
        """(frames, extensometers) engineering strain, NaN where not read."""
        return np.array(self.eng).reshape(len(self.times), len(names))


def _write_frame_files(staged: dict[str, AtomicFile], source: _Source, stop: Callable[[], None],
                       progress: ProgressBar | None) -> _Written:
    """``fields.csv``, ``p0_trace.csv`` and ``extensometers.csv``, one frame with results after another."""
    fields_csv, trace = staged["fields.csv"], staged["p0_trace.csv"]
    extensometers = staged["extensometers.csv"]
    trace.write(",".join(P0_COLUMNS) + "\n")
    scale = source.config.px_per_mm
    first = source.first
    mm_fields = mm_columns(first is not None and bool(first.stereo), bool(scale))
    in_space = source.stereo is not None      # lengths in mm measured in space, whatever the scale
    extensometers.write(",".join(EXTENSOMETER_COLUMNS + (EXTENSOMETER_MM_COLUMNS if scale or in_space else ()))
                        + "\n")
    written = _Written()
    extras_seen: list[str] | None = None             # the extra columns of the first frame: the file's
    for result in _chain(source.first, source.results):
        stop()
        if progress is not None:
            progress.update(written.frames, "frames to CSV")
        if extras_seen is None:
            extras_seen = [name for name in EXTRA_COLUMNS if _has_extra(result, name)]
            fields_csv.write(",".join(list(LEADING_COLUMNS) + extras_seen + list(STRAIN_COLUMNS) + list(mm_fields))
                             + "\n")
            written.points = len(result.u)
        readings = _write_fields_rows(fields_csv, result, extras_seen, mm_fields, source, written)
        if written.t0 is None:
            written.t0 = int(result.timestamp_ns)
        time_s = (int(result.timestamp_ns) - written.t0) / 1e9
        extensometers.write(csv_rows(extensometer_columns(result.frame_index, time_s, readings, scale),
                                     len(readings.names)))
        written.times.append(time_s)
        written.frame_numbers.append(int(result.frame_index))
        written.eng.append(np.asarray(readings.eng_strain, dtype=np.float64))
        if readings.l0_mm is not None and written.l0_mm is None:
            written.l0_mm = [float(v) for v in readings.l0_mm]
        _write_p0_row(trace, result, source.p0_id, time_s, written)
        written.frames += 1
    if extras_seen is None:
        fields_csv.write(",".join(LEADING_COLUMNS + STRAIN_COLUMNS + mm_fields) + "\n")
    return written


def _has_extra(result: RecordedResults, name: str) -> bool:
    """Whether ``result`` holds the extra column ``name`` (``EXTRA_COLUMNS``), one value per point."""
    values = getattr(result, name)
    return values is not None and len(values) == len(result.u)


def _write_fields_rows(fields_csv: AtomicFile, result: RecordedResults, extras_seen: list[str],
                       mm_fields: tuple[str, ...], source: _Source, written: _Written) -> ExtensometerReadings:
    """One frame's rows of ``fields.csv`` (its strain recomputed, its values added to the colour ranges, the
    ``mm_fields`` of the header: a stereo frame's recorded 3D columns as recorded, NaN where a frame lacks them);
    returns the frame's extensometer readings."""
    n = len(result.u)
    extras = {name: getattr(result, name) for name in EXTRA_COLUMNS if _has_extra(result, name)}
    for name in extras_seen:          # a frame without an extra the first one had: blank cells
        extras.setdefault(name, np.full(n, "", dtype=object))
    extras = {name: extras[name] for name in extras_seen}
    columns = result_columns(result.frame_index, result.timestamp_ns, result.point_id, result.x,
                             result.y, result.u, result.v, result.zncc, result.ok, extras)
    stage = source.stage
    assert stage is not None          # a frame with results: the stage was placed on the first
    strain_field, readings = source.frame_strain(result)
    if strain_field is not None:
        columns.update(exx=strain_field.exx, eyy=strain_field.eyy, exy=strain_field.exy)
        source.ranges.add(columns, np.asarray(result.ok, dtype=bool))
        if mm_fields == FIELD_MM_COLUMNS:
            columns.update(zip(FIELD_MM_COLUMNS, stage.displacements_mm(result.u, result.v)))
    else:                             # not the reference's points: no strain to speak of
        written.other_points += 1
        columns.update({name: np.full(n, np.nan) for name in STRAIN_COLUMNS + mm_fields})
    if mm_fields == STEREO_COLUMNS:   # recorded per point, whatever the points: as recorded
        columns.update(stereo_columns(result.stereo) or {name: np.full(n, np.nan) for name in STEREO_COLUMNS})
    fields_csv.write(csv_rows(columns, n))
    return readings


def _write_p0_row(trace: AtomicFile, result: RecordedResults, p0_id: int, time_s: float, written: _Written) -> None:
    """P0's row of ``p0_trace.csv`` for one frame (counted missing where the frame has no point ``p0_id``)."""
    where = np.flatnonzero(result.point_id == p0_id)
    if not where.size:
        written.p0_missing += 1
        return
    k = int(where[0])
    trace.write(csv_rows({
        "frame": int(result.frame_index), "timestamp_ns": int(result.timestamp_ns),
        "time_s": time_s, "x": float(result.x[k]),
        "y": float(result.y[k]), "u": float(result.u[k]), "v": float(result.v[k]),
        "zncc": float(result.zncc[k]), "ok": bool(result.ok[k])}, 1))
    written.p0_rows += 1


def _events_csv(events: Sequence[RecordedEvent], t0: int | None) -> str:
    """The text of ``events.csv``: each event's time in s since ``t0`` (ns; 0 when None)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(EVENT_COLUMNS)
    for event in events:
        writer.writerow([scalar_text((event.timestamp_ns - (t0 or 0)) / 1e9), event.kind, event.level,
                         " ".join(str(event.message).splitlines()), event.timestamp_ns])
    return buffer.getvalue()


def _frame_notes(path: str, source: _Source, written: _Written) -> list[str]:
    """What people should know of the frames written: P0 missing, no results, no extensometers, other points."""
    notes = []
    frames = written.frames
    if frames and written.p0_missing:
        notes.append(f"P0 (point {source.p0_id}) is missing from {written.p0_missing} of {frames} frames' results")
    if frames == 0:
        notes.append(f"{path} holds no tracking results (/dic/results): fields.csv, p0_trace.csv and "
                     f"extensometers.csv have headers only")
    elif not source.names:
        notes.append("the recording has no extensometers: extensometers.csv has the header only "
                     "(add some with --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2)")
    if written.other_points:
        notes.append(f"{written.other_points} of {frames} frames track other points than the first: no strain "
                     f"and no extensometer readings for them")
    if frames and source.stereo is not None:
        notes.append("a stereo recording: X_mm..W_mm, stereo_status, exx, eyy, exy and the extensometers are the "
                     "session's 3D results as recorded: the strain on the specimen's surface (Green-Lagrange), the "
                     "extensometers' lengths in space (L0_mm, L_mm; no length in px); `livedic replay` measures "
                     "it again")
    return notes


def _plot_extensometer_file(staged: dict[str, AtomicFile], path: str, source: _Source, written: _Written) -> None:
    """``extensometers.png``: each extensometer's strain against time (a note in the plot when there is none)."""
    stage = source.stage
    title = f"{os.path.basename(path)}: virtual extensometers"
    l0_mm = None
    if stage is not None and source.stereo is not None:
        l0, l0_mm = [], written.l0_mm
        title += " in space (stereo)"
    elif stage is not None:
        l0 = [e.length_px for e in stage.extensometers]
        title += f" ({stage.config.px_per_mm:g} px/mm)" if stage.config.px_per_mm else ""
    else:
        l0 = []
    plot_extensometers(staged["extensometers.png"].handle, written.times, source.names, l0,
                       written.eng_strain(source.names), title=title, scale=source.config.px_per_mm, l0_mm=l0_mm,
                       empty_note="no tracking results" if written.frames == 0 else "no extensometers in this "
                       "recording\n(livedic export --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2)")


def _stress_strain_files(staged: dict[str, AtomicFile], path: str, source: _Source, written: _Written,
                         stress: StressOptions | None) -> dict[str, Any] | None:
    """``STRESS_FILES`` with a force (``--load`` or the recorded one); what ``session.json`` says of them."""
    if source.load is None or stress is None:
        return None
    return _write_stress_strain(staged, source.load, stress.area_mm2, written.frame_numbers, written.times,
                                written.eng_strain(source.names), source.names,
                                title=f"{os.path.basename(path)}: stress-strain (A0 {stress.area_mm2:g} mm^2, force "
                                      f"{_force_label(stress)})")


def _session_json(path: str, source: _Source, written: _Written, events: Sequence[RecordedEvent], notes: list[str],
                  strain: dict[str, Any] | None, stress: StressOptions | None,
                  stress_summary: dict[str, Any] | None) -> dict[str, Any]:
    """``session.json``: the session metadata and the ``EXPORT_KEY`` entry saying how the files were made."""
    session = dict(source.metadata)
    delivered = _frames_delivered(source.recording, session)
    session[EXPORT_KEY] = {
        "source": os.path.abspath(path), "exported_at": datetime.now(timezone.utc).isoformat(),
        "frames_with_results": written.frames, **delivered, "points": written.points, "events": len(events),
        "p0_id": source.p0_id, "p0_id_from": source.p0_how, "time_origin_ns": written.t0,
        "truncated": source.recording.info.truncated, "notes": list(notes),
        "strain": _strain_settings(source.stage, source.config, strain)}
    if stress is not None:
        session[EXPORT_KEY]["stress"] = {"load": stress.load, "load_offset_s": stress.offset_s,
                                         "area_mm2": stress.area_mm2, **(stress_summary or {})}
        if isinstance(source.load, RecordedForce):
            session[EXPORT_KEY]["stress"]["recorded_source"] = source.load.source
    return session


def _write_fields(path, directory, fields, shown, ranges, stage, first, frames, t0, overwrite, stop, progress, *,
                  title_note, in_space=False):
    """The second pass over the recording: ``stream.export.field_export.FieldWriter`` on every frame with results
    (``in_space``: a stereo recording, its strain as recorded)."""
    from livedic.acquire.recording.reader import Recording
    if overwrite:
        remove_stale(directory, fields)
    writer = FieldWriter(directory, fields, shown, ranges.limits, (first.x, first.y), stage.windows.step, frames,
                         title_note=title_note)
    recording = Recording(path)
    stereo = StereoStrainRecord(recording, stage.placed.names) if in_space else None
    images = RecordedImages(path) if fields.coloured else None
    if progress is not None:
        progress.close()
        progress.total = frames
        progress.update(0, "drawing maps, video and VTK", force=True)
    position = 0
    try:
        with _stopped_in(lambda: f"while drawing the maps, video and VTK (frame {position + 1} of {frames}): "
                                 f"{directory} holds the CSV files, plots and session.json, complete, and "
                                 f"{writer.report.written(fields)}, each complete"
                                 f"{_not_written(writer.report, fields)}"):
            for position, result in enumerate(recording.results()):
                stop()
                if progress is not None:
                    progress.update(position, "drawing maps, video and VTK")
                if not np.array_equal(result.point_id, first.point_id):
                    writer.report.other_points += 1
                    continue
                strain_field, _ = (stereo.at(result, stage.placed) if stereo is not None
                                   else stage.compute(result.u, result.v, result.ok))
                values = {"u": result.u, "v": result.v, "exx": strain_field.exx, "eyy": strain_field.eyy,
                          "exy": strain_field.exy,
                          "zncc": result.zncc, "status": result.status, "point_id": result.point_id}
                frame = images.at(result.timestamp_ns) if writer.wants_image(position) else None
                writer.add(position, result.frame_index, (int(result.timestamp_ns) - t0) / 1e9, values, result.ok,
                           image=None if frame is None else frame.image,
                           pixel_format="" if frame is None else frame.pixel_format)
            writer.finish()
    except BaseException:
        writer.discard()
        raise
    if progress is not None:
        progress.update(frames, "drawing maps, video and VTK", force=True)
        progress.close()
    return writer.report


def _not_written(report, fields):
    missing = ([video_name(fields.video)] if fields.video and not report.video else []) + (
        [PVD_FILE] if fields.vtk and not report.pvd else [])
    return f"; not written: {', '.join(missing)}" if missing else ""


def _fields_settings(fields, shown, ranges, report, stage):
    """What ``session.json`` says of the maps, video and VTK files."""
    return {"maps": list(fields.maps), "every": fields.every, "maps_written": report.maps,
            "video": os.path.basename(report.video) if report.video else None, "video_frames": report.video_frames,
            "video_fps": fields.video_fps, "video_codec": VIDEO_FOURCC, "vtu_written": report.vtu,
            "pvd": os.path.basename(report.pvd) if report.pvd else None, "opacity": fields.opacity,
            "colour_map": COLOUR_MAP, "surface_step_px": stage.windows.step,
            "colour_ranges": {name: {"lo": lo, "hi": hi, "unit": shown[name].unit,
                                     "fixed": name in fields.ranges} for name, (lo, hi) in ranges.limits.items()},
            "frames_without_image": report.no_image, "frames_with_other_points": report.other_points}


def _field_notes(report):
    notes = []
    if report.no_image:
        notes.append(f"{plural(report.no_image, 'frame')} with results have no camera image in the recording: "
                     f"no map or video frame for them")
    if report.other_points:
        notes.append(f"{plural(report.other_points, 'frame')} track other points than the first: no map, video "
                     f"frame or VTK file for them")
    return notes


def _frames_delivered(recording, session):
    """How many frames the session delivered in the end, and how that is known, for ``session.json``.

    The recording holds every frame the source delivered (recorded before the queue, dropped or not), so
    they are counted there (the file's statistics, else a scan). The session metadata was written when
    the first frame came: a source's own ``frames_delivered`` in it (a camera's) was that moment's count,
    so ``session`` (the metadata, copied) gets the final count there, the snapshot kept beside it.
    """
    from livedic.acquire.recording.schema import TOPIC_IMAGE
    count = recording.count(TOPIC_IMAGE)
    how = f"the frames in the recording ({TOPIC_IMAGE}), where the session records every frame its source delivers"
    if recording.info.truncated:
        how += "; the recording was cut short: at least this many"
    settings = session.get("source_settings")
    if isinstance(settings, dict) and "frames_delivered" in settings:
        session["source_settings"] = {**settings, "frames_delivered": count,
                                      "frames_delivered_at_start": settings["frames_delivered"]}
    return {"frames_delivered": count, "frames_delivered_from": how}
