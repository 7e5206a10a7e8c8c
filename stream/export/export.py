"""``livedic export``: a recording's results as CSV files anyone can open.

``livedic export FILE.mcap -o DIR`` writes six files into DIR (created if missing):

``p0_trace.csv``
    The traced point P0 over time, one row per frame with results:
    ``frame,timestamp_ns,time_s,x,y,u,v,zncc,ok``. ``time_s`` is seconds since the
    first frame with results (the reference frame). P0's id is read from the session
    metadata (``p0_id`` when present, else the ``point_ids`` note, "P0 is point 0").
``fields.csv``
    Every frame, every point, long format:
    ``frame,timestamp_ns,point_id,x,y,u,v,zncc,ok`` then the extras the recording holds
    (``status``, ``ux``, ``uy``, ``vx``, ``vy``, ``iterations``) - the same columns as
    ``livedic replay``, so the two files can be compared line by line - then the strain
    ``exx,eyy,exy`` (NaN where a point has none; see below).
``extensometers.csv``
    ``frame,time_s,name,L0_px,L_px,eng_strain,true_strain,ok``: one row per frame and
    virtual extensometer (``ok`` 1/0; NaN where not ok), ``time_s`` as in ``p0_trace.csv``.
    Only the header when the recording has no extensometers (a note says so).
``extensometers.png``
    Engineering strain of each extensometer against time, gaps where an end was lost.
``events.csv``
    ``time,kind,level,message,timestamp_ns``: ``time`` in seconds on the same clock as
    ``p0_trace.csv`` (``timestamp_ns`` is the raw frame clock).
``stress_strain.csv`` and ``stress_strain.png`` (with ``--load csv:FILE`` and a cross-section, or
    without ``--load`` when the recording holds the machine's force on ``/machine/force``)
    ``frame,time_s,force_N,eng_strain,eng_stress_MPa,true_strain,true_stress_MPa``: the force
    interpolated onto each frame's ``time_s`` (NaN where the file has none), or the force recorded
    for that frame (NaN where none was), the ``axial`` extensometer's engineering strain, stress
    ``F / A0``, and the true values up to uniform elongation (NaN after the frame of maximum
    force: ``stream.stages.stress``); the plot of both curves. The recording (or the options) must have
    an ``axial`` extensometer. The recorded force takes its cross-section from ``--area`` or
    ``--width --thickness``, else from the session metadata's ``area_mm2``; a ``--load`` given
    replaces the recorded force (a note says so).
``session.json``
    The session metadata (method, parameters, source, ROI, ...), plus a
    ``livedic.export`` entry saying where the files came from, whether the
    recording was complete, and how many frames the session delivered in the end
    (``frames_delivered``, counted in the recording; ``frames_delivered_from`` says so).

Strain and extensometers are *recomputed* from the recorded displacements with the
settings the recording was made with (``stream.stages.strain.StrainConfig.from_metadata``: the
strain window and measure, the extensometers as placed), on the recorded reference
points (P0 first), one frame after another: the same ``StrainStage`` as the live
session, so the strain of a recording is computed one way everywhere. The options
``--strain-window --strain-measure --gauge-length --extensometer --scale`` replace the
recorded settings (offline re-analysis; ``--gauge-length``/``--extensometer`` replace
all the recorded extensometers).

Numbers are written at full precision (the shortest text that reads back as the
same float64), NaN as ``nan``, ``ok`` as 1/0: a value read back from these files is
bit-for-bit the recorded one.

Then the fields as pictures (``stream.export.field_export``, options ``--maps --every --video
--vtk --map-range ...``): ``maps/Q/Q_FRAME.png``, ``overlay_Q.mp4``, ``vtk/frame_FRAME.vtu``
and ``fields.pvd``, in a second pass over the recording (the colour ranges, one per quantity
for the whole test, are known only after the first), and ``session.json`` again with a
``fields`` entry saying what was written.

Every file is written under a temporary name and all six are renamed into place
only when all are complete, so an error or Ctrl-C never leaves a half-written
file. The pictures are each written whole as they come. Ctrl-C or SIGTERM
(``StopSignals``) stops the export at the next frame: while the CSV files are
written nothing is left; later the CSV files and the pictures finished stay, and
one line says so (exit 130 or 143). Existing files are not replaced unless ``--overwrite``. A truncated recording
(crash, kill, disk full) exports what can be recovered and says so in a note; the
``truncated`` flag is the reader's (``RecordingInfo.truncated``), never read from
the note's text.

The helpers here (CSV formatting, atomic files, reader notes, P0 lookup) are also
used by ``stream.replay.replay``.
"""

import csv
import io
import logging
import math
import os
import re
import signal
import sys
import threading
from contextlib import contextmanager
from datetime import datetime, timezone

import numpy as np

from livedic.acquire.atomic_file import atomic_files
from livedic.stream.output.files import AtomicFile, check_output_folder, json_text, write_text_atomic
from livedic.stream.output.csv_text import csv_rows, scalar_text
from livedic.stream.export.field_export import (COLOUR_MAP, NO_FIELDS, PVD_FILE, VIDEO_FOURCC, ColourRanges, FieldOptions,
                                         FieldWriter, RecordedImages, quantities, remove_stale, video_name)

LEADING_COLUMNS = ("frame", "timestamp_ns", "point_id", "x", "y", "u", "v", "zncc", "ok")
EXTRA_COLUMNS = ("status", "ux", "uy", "vx", "vy", "iterations")
P0_COLUMNS = ("frame", "timestamp_ns", "time_s", "x", "y", "u", "v", "zncc", "ok")
EVENT_COLUMNS = ("time", "kind", "level", "message", "timestamp_ns")
STRAIN_COLUMNS = ("exx", "eyy", "exy")
EXTENSOMETER_COLUMNS = ("frame", "time_s", "name", "L0_px", "L_px", "eng_strain", "true_strain", "ok")
EXPORT_FILES = ("p0_trace.csv", "fields.csv", "events.csv", "session.json", "extensometers.csv", "extensometers.png")
BINARY_FILES = ("extensometers.png", "stress_strain.png")
STRESS_FILES = ("stress_strain.csv", "stress_strain.png")
EXPORT_KEY = "livedic.export"

_READER_LOGGER = "livedic.acquire.recording.reader"


def result_columns(frame_index, timestamp_ns, point_id, x, y, u, v, zncc, ok, extras):
    """The long-format columns of one frame (``LEADING_COLUMNS`` then ``extras`` in ``EXTRA_COLUMNS`` order)."""
    columns = {"frame": int(frame_index), "timestamp_ns": int(timestamp_ns), "point_id": point_id,
               "x": x, "y": y, "u": u, "v": v, "zncc": zncc, "ok": np.asarray(ok, dtype=bool)}
    for name in EXTRA_COLUMNS:
        if name in extras:
            columns[name] = extras[name]
    return columns


# ----------------------------------------------------------------------------- files

# The atomic writer shared by every output of livedic (kept under its old name for callers).
StagedFile = AtomicFile


# ----------------------------------------------------------------------------- recording helpers

@contextmanager
def reader_notes():
    """Collect the notes ``acquire.recording.reader`` logs (truncated file ...) instead of printing them raw.

    Yields a list that fills with one line per distinct note ("note: " prefix removed).
    The lines are for people; what a program acts on is the reader's ``RecordingInfo``.
    """
    notes = []

    class _Collect(logging.Handler):
        def emit(self, record):
            text = record.getMessage()
            text = text[len("note: "):] if text.startswith("note: ") else text
            if text not in notes:
                notes.append(text)

    logger = logging.getLogger(_READER_LOGGER)
    handler = _Collect(level=logging.INFO)
    previous = logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield notes
    finally:
        logger.removeHandler(handler)
        logger.propagate = previous


def p0_point_id(metadata):
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


def session_or_note(recording):
    """(session metadata dict, note or "") of a ``Recording``: one without metadata gives {} and a note."""
    from livedic.acquire.recording.errors import NoSessionMetadata
    try:
        return recording.session(), ""
    except NoSessionMetadata as missing:
        return {}, str(missing)


def read_session_or_note(path):
    """``session_or_note`` of the recording at ``path`` (``RecordingError`` if it is not one)."""
    from livedic.acquire.recording.reader import Recording
    return session_or_note(Recording(path))


def say(message):
    print(f"livedic: {message}", file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- strain

def reference_geometry(metadata, first, p0_id):
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


def strain_stage(metadata, first, p0_id, overrides=None):
    """The ``stream.stages.strain.StrainStage`` of a recording (its settings, ``overrides`` replacing them).

    Raises
    ------
    ValueError
        A bad setting, or an extensometer end away from the tracked points (one line).
    """
    from livedic.stream.stages.strain import StrainConfig
    config = StrainConfig.from_metadata(metadata, **(overrides or {}))
    points, p0, roi, step, subset = reference_geometry(metadata, first, p0_id)
    return config.place(points, p0=p0, roi=roi, step=step, subset=subset)


def extensometer_columns(frame_index, time_s, readings):
    """The ``EXTENSOMETER_COLUMNS`` of one frame's ``ExtensometerReadings`` (one row per extensometer)."""
    return {"frame": int(frame_index), "time_s": float(time_s),
            "name": np.array([_csv_cell(name) for name in readings.names], dtype=object),
            "L0_px": readings.l0_px, "L_px": readings.length_px, "eng_strain": readings.eng_strain,
            "true_strain": readings.true_strain, "ok": np.asarray(readings.ok, dtype=bool)}


def _csv_cell(text):
    """``text`` as one CSV cell (quoted only where CSV needs it)."""
    text = str(text)
    if any(c in text for c in ',"\n\r'):
        return '"' + text.replace('"', '""') + '"'
    return text


def _lost_readings(placed):
    """Readings of ``placed`` extensometers for a frame whose points differ from the reference's: none ok."""
    from livedic.dic.strain.extensometer import ExtensometerReadings, ExtensometerStatus
    n = len(placed.names)
    nan = np.full(n, np.nan)
    l0 = np.array([e.length_px for e in placed.extensometers], dtype=np.float64)
    return ExtensometerReadings(names=placed.names, l0_px=l0, length_px=nan, eng_strain=nan.copy(),
                                true_strain=nan.copy(),
                                status=np.full(n, int(ExtensometerStatus.END_LOST), dtype=np.int32))


def plot_extensometers(handle, times, names, l0_px, strains, *, title, scale=None, empty_note=""):
    """Write ``extensometers.png`` to ``handle``: engineering strain (%) against time, one line each.

    ``strains`` is (frames, extensometers), NaN where not ok: the line has a gap there
    (points drawn too, so a reading between two gaps still shows). ``l0_px`` may be shorter than
    ``names`` (a recording with no results places no extensometer): those have no L0 in the legend.
    """
    from matplotlib.figure import Figure

    figure = Figure(figsize=(8, 4.5), dpi=100, layout="constrained")
    axes = figure.add_subplot()
    times = np.asarray(times, dtype=np.float64)
    strains = np.asarray(strains, dtype=np.float64).reshape(len(times), len(names))
    for k, name in enumerate(names):
        if k < len(l0_px):
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


# ----------------------------------------------------------------------------- export

def export_recording(path, directory, *, overwrite=False, strain=None, stress=None, fields=NO_FIELDS, stop=None,
                     progress=None):
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
    from livedic.acquire.recording.reader import Recording
    from livedic.stream.stages.strain import StrainConfig

    path, directory = os.fspath(path), os.fspath(directory)
    check_output_folder(directory, "-o")
    outputs = EXPORT_FILES + (STRESS_FILES if stress is not None else ())
    targets = {name: os.path.join(directory, name) for name in outputs}
    existing = [name for name, target in targets.items() if os.path.lexists(target)] + fields.existing(directory)
    stop = stop or (lambda: None)
    if existing and not overwrite:
        raise ValueError(f"{directory} already holds {', '.join(existing)}: pass --overwrite to replace "
                         f"{'it' if len(existing) == 1 else 'them'}, or choose another folder")
    with reader_notes() as notes:
        recording = Recording(path)                             # checks the file before DIR is made
        metadata, session_note = session_or_note(recording)
        if session_note:
            notes.append(session_note)
        p0_id, p0_how = p0_point_id(metadata)
        config = StrainConfig.from_metadata(metadata, **(strain or {}))   # bad settings: before DIR is made
        results = recording.results()
        first = next(results, None)
        stage = strain_stage(metadata, first, p0_id, strain) if first is not None else None
        names = stage.placed.names if stage is not None else tuple(e.name for e in config.extensometers)
        load = _open_stress_load(stress, names, recording)      # bad load or no axial: before DIR is made
        shown = quantities(config.scale, fields.strain_unit, config.measure,
                           stage.vsg_px if stage is not None else None)
        ranges = ColourRanges(shown, fields.ranges, fields.coloured)
        created = not os.path.isdir(directory)
        with _stopped_in(f"while writing the CSV files: nothing was written"
                         f"{f' ({directory} removed again)' if created else ''}"), \
                atomic_files(targets, binary=BINARY_FILES) as staged:
            fields_csv, trace = staged["fields.csv"], staged["p0_trace.csv"]
            extensometers = staged["extensometers.csv"]
            fields_header = None
            trace.write(",".join(P0_COLUMNS) + "\n")
            extensometers.write(",".join(EXTENSOMETER_COLUMNS) + "\n")
            frames = p0_rows = points = 0
            p0_missing = other_points = 0
            t0 = None
            extras_seen = None
            times, eng, frame_numbers = [], [], []
            for result in _chain(first, results):
                stop()
                if progress is not None:
                    progress.update(frames, "frames to CSV")
                extras = {name: getattr(result, name) for name in EXTRA_COLUMNS
                          if getattr(result, name) is not None and len(getattr(result, name)) == len(result.u)}
                if fields_header is None:
                    extras_seen = [name for name in EXTRA_COLUMNS if name in extras]
                    fields_header = list(LEADING_COLUMNS) + extras_seen + list(STRAIN_COLUMNS)
                    fields_csv.write(",".join(fields_header) + "\n")
                    points = len(result.u)
                n = len(result.u)
                for name in extras_seen:          # a frame without an extra the first one had: blank cells
                    extras.setdefault(name, np.full(n, "", dtype=object))
                extras = {name: extras[name] for name in extras_seen}
                columns = result_columns(result.frame_index, result.timestamp_ns, result.point_id, result.x,
                                         result.y, result.u, result.v, result.zncc, result.ok, extras)
                if np.array_equal(result.point_id, first.point_id):
                    field, readings = stage.compute(result.u, result.v, result.ok)
                    columns.update(exx=field.exx, eyy=field.eyy, exy=field.exy)
                    ranges.add(columns, np.asarray(result.ok, dtype=bool))
                else:                             # not the reference's points: no strain to speak of
                    other_points += 1
                    readings = _lost_readings(stage.placed)
                    columns.update({name: np.full(n, np.nan) for name in STRAIN_COLUMNS})
                fields_csv.write(csv_rows(columns, n))
                if t0 is None:
                    t0 = int(result.timestamp_ns)
                time_s = (int(result.timestamp_ns) - t0) / 1e9
                extensometers.write(csv_rows(extensometer_columns(result.frame_index, time_s, readings),
                                             len(readings.names)))
                times.append(time_s)
                frame_numbers.append(int(result.frame_index))
                eng.append(np.asarray(readings.eng_strain, dtype=np.float64))
                where = np.flatnonzero(result.point_id == p0_id)
                if where.size:
                    k = int(where[0])
                    trace.write(csv_rows({
                        "frame": int(result.frame_index), "timestamp_ns": int(result.timestamp_ns),
                        "time_s": time_s, "x": float(result.x[k]),
                        "y": float(result.y[k]), "u": float(result.u[k]), "v": float(result.v[k]),
                        "zncc": float(result.zncc[k]), "ok": bool(result.ok[k])}, 1))
                    p0_rows += 1
                else:
                    p0_missing += 1
                frames += 1
            if fields_header is None:
                fields_csv.write(",".join(LEADING_COLUMNS + STRAIN_COLUMNS) + "\n")
            events = recording.events()
            if t0 is None and events:
                t0 = min(event.timestamp_ns for event in events)
            buffer = io.StringIO()
            writer = csv.writer(buffer, lineterminator="\n")
            writer.writerow(EVENT_COLUMNS)
            for event in events:
                writer.writerow([scalar_text((event.timestamp_ns - (t0 or 0)) / 1e9), event.kind, event.level,
                                 " ".join(str(event.message).splitlines()), event.timestamp_ns])
            staged["events.csv"].write(buffer.getvalue())
            if frames and p0_missing:
                notes.append(f"P0 (point {p0_id}) is missing from {p0_missing} of {frames} frames' results")
            if frames == 0:
                notes.append(f"{path} holds no tracking results (/dic/results): fields.csv, p0_trace.csv and "
                             f"extensometers.csv have headers only")
            elif not names:
                notes.append("the recording has no extensometers: extensometers.csv has the header only "
                             "(add some with --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2)")
            if other_points:
                notes.append(f"{other_points} of {frames} frames track other points than the first: no strain "
                             f"and no extensometer readings for them")
            if stage is not None:
                l0 = [e.length_px for e in stage.extensometers]
                title = (f"{os.path.basename(path)}: virtual extensometers"
                         + (f" ({stage.config.scale:g} px/mm)" if stage.config.scale else ""))
            else:
                l0, title = [], f"{os.path.basename(path)}: virtual extensometers"
            plot_extensometers(staged["extensometers.png"].handle, times, names, l0,
                               np.array(eng).reshape(len(times), len(names)), title=title,
                               scale=config.scale,
                               empty_note="no tracking results" if frames == 0 else "no extensometers in this "
                               "recording\n(livedic export --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2)")
            stress_summary = None
            if load is not None:
                stress_summary = _write_stress_strain(staged, load, stress.area_mm2, frame_numbers, times,
                                                      np.array(eng).reshape(len(times), len(names)), names,
                                                      title=f"{os.path.basename(path)}: stress-strain (A0 "
                                                            f"{stress.area_mm2:g} mm^2, force "
                                                            f"{_force_label(stress)})")
            session = dict(metadata)
            delivered = _frames_delivered(recording, session)
            truncated = recording.info.truncated
            session[EXPORT_KEY] = {
                "source": os.path.abspath(path), "exported_at": datetime.now(timezone.utc).isoformat(),
                "frames_with_results": frames, **delivered, "points": points, "events": len(events),
                "p0_id": p0_id, "p0_id_from": p0_how, "time_origin_ns": t0,
                "truncated": truncated, "notes": list(notes),
                "strain": _strain_settings(stage, config, strain)}
            if stress is not None:
                session[EXPORT_KEY]["stress"] = {"load": stress.load, "load_offset_s": stress.offset_s,
                                                 "area_mm2": stress.area_mm2, **stress_summary}
                if isinstance(load, RecordedForce):
                    session[EXPORT_KEY]["stress"]["recorded_source"] = load.source
            staged["session.json"].write(json_text(session))
        report = None
        if fields.wanted and frames:
            report = _write_fields(path, directory, fields, shown, ranges, stage, first, frames, t0, overwrite,
                                   stop, progress, title_note=os.path.basename(path))
            session[EXPORT_KEY]["fields"] = _fields_settings(fields, shown, ranges, report, stage)
            write_text_atomic(targets["session.json"], json_text(session))
            notes.extend(_field_notes(report))
        elif fields.wanted:
            notes.append("no tracking results: no maps, video or VTK files")
    return {"directory": directory, "files": [targets[name] for name in outputs], "frames": frames,
            "points": points, "events": len(events), "p0_id": p0_id, "p0_rows": p0_rows,
            "truncated": truncated, "notes": list(notes), "extensometers": list(names),
            "strain": stage.describe() if stage is not None else "", "stress": stress_summary, "fields": report}


# ----------------------------------------------------------------------------- maps, video, VTK

def _write_fields(path, directory, fields, shown, ranges, stage, first, frames, t0, overwrite, stop, progress, *,
                  title_note):
    """The second pass over the recording: ``stream.export.field_export.FieldWriter`` on every frame with results."""
    from livedic.acquire.recording.reader import Recording
    if overwrite:
        remove_stale(directory, fields)
    writer = FieldWriter(directory, fields, shown, ranges.limits, (first.x, first.y), stage.windows.step, frames,
                         title_note=title_note)
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
            for position, result in enumerate(Recording(path).results()):
                stop()
                if progress is not None:
                    progress.update(position, "drawing maps, video and VTK")
                if not np.array_equal(result.point_id, first.point_id):
                    writer.report.other_points += 1
                    continue
                field, _ = stage.compute(result.u, result.v, result.ok)
                values = {"u": result.u, "v": result.v, "exx": field.exx, "eyy": field.eyy, "exy": field.exy,
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


# ----------------------------------------------------------------------------- stopping

class ExportStopped(Exception):
    """A stop signal ended the export; ``state`` (one line) says what the folder holds."""

    def __init__(self, signal_name, signum):
        super().__init__(signal_name)
        self.signal_name = signal_name
        self.signum = int(signum)
        self.state = ""


class StopSignals:
    """SIGINT (Ctrl-C) and SIGTERM during ``livedic export``: the first stops the export at the next frame.

    The handler only takes note; ``check`` (called once per frame) raises ``ExportStopped``, so a
    stop never lands inside a library call that is writing a file. A second signal gives up at
    once (``KeyboardInterrupt``). Installed only in the main thread (signals reach no other).
    """

    def __init__(self):
        self.received = None
        self._previous = {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, _frame):
        if self.received is not None:
            raise KeyboardInterrupt
        self.received = signal.Signals(signum)

    def check(self):
        if self.received is not None:
            raise ExportStopped(self.received.name, self.received.value)

    def __exit__(self, *exc):
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        return False


@contextmanager
def _stopped_in(state):
    """Give an ``ExportStopped`` leaving this block its ``state`` (text, or a callable for the text at that time)."""
    try:
        yield
    except ExportStopped as stopped:
        if not stopped.state:
            stopped.state = state() if callable(state) else state
        raise


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


class RecordedForce:
    """The force recorded on ``/machine/force``, one value per tracked frame.

    Attributes
    ----------
    forces : dict
        Frame index -> force (N; NaN where the load had no value for that frame).
    source : str
        The load URI the session recorded (the last one seen; "" when none was written).
    """

    def __init__(self, forces, source=""):
        self.forces = dict(forces)
        self.source = str(source)

    @classmethod
    def read(cls, recording):
        """The force samples of a ``Recording`` (an empty ``forces`` for recordings without them)."""
        forces, source = {}, ""
        for sample in recording.force_samples():
            forces[int(sample.frame_index)] = float(sample.force_N)
            source = sample.source or source
        return cls(forces, source)

    def on_frames(self, frames):
        """Force at each of ``frames`` (indices): the recorded value, NaN for a frame without one."""
        return np.array([self.forces.get(int(frame), math.nan) for frame in frames], dtype=np.float64)


def _force_on_frames(load, frames, times):
    """Force per frame: by frame index from the recording, or the load interpolated onto ``times``."""
    if isinstance(load, RecordedForce):
        return load.on_frames(frames)
    return load.force_at(np.asarray(times, dtype=np.float64))


def _force_label(stress):
    """What the plot title calls the force: the file's name, or the recorded channel."""
    from livedic.acquire.recording.schema import TOPIC_FORCE
    if stress.recorded:
        return f"recorded {TOPIC_FORCE}"
    return os.path.basename(stress.load[len('csv:'):])


def _open_stress_load(stress, names, recording=None):
    """The ``LoadSource`` of ``stress``, or the ``RecordedForce`` of ``recording`` (None without ``stress``).

    ValueError (one line) if there is no axial extensometer."""
    if stress is None:
        return None
    from livedic.acquire.force import open_load
    from livedic.dic.strain.extensometer import AXIAL
    if AXIAL not in names:
        raise ValueError(f"the stress-strain curve needs an '{AXIAL}' extensometer, and this recording has "
                         f"{'only ' + ', '.join(names) if names else 'none'}: add --gauge-length L[,W] "
                         f"(or --extensometer {AXIAL}=x1,y1,x2,y2)")
    if stress.recorded:
        return RecordedForce.read(recording)
    return open_load(stress.load, offset_s=stress.offset_s)


def stress_from_args(args):
    """``StressOptions`` of ``livedic export`` / ``report`` and note lines for people.

    With ``--load``, that load (a note when the recording also holds force samples, which it
    replaces); without, the force recorded on ``/machine/force`` when the recording holds some
    (A0 from the options or the session's ``area_mm2``), else None. Bad options raise before the
    recording is read; ValueError (one line) as ``stream.stages.stress.stress_options_from_args``.
    """
    from livedic.acquire.recording.reader import Recording
    from livedic.acquire.recording.schema import TOPIC_FORCE
    from livedic.stream.stages.stress import stress_options_from_args
    load = getattr(args, "load", None)
    section = any(getattr(args, name, None) is not None for name in ("area", "width", "thickness"))
    if load is not None and section:
        stress = stress_options_from_args(args)               # bad options: one line, before anything is read
    with reader_notes():                                      # the command's own read reports them, once
        recording = Recording(os.fspath(args.recording))
        recorded = RecordedForce.read(recording)
        metadata = session_or_note(recording)[0] if recorded.forces or (load is not None and not section) else {}
    if load is not None:
        if not section:                                       # A0 from the session, when it recorded one
            stress = stress_options_from_args(args, metadata=metadata)
        notes = [f"--load {stress.load} is the force here, not the one recorded on {TOPIC_FORCE} "
                 f"({plural(len(recorded.forces), 'frame')})"] if recorded.forces else []
        return stress, notes
    return stress_options_from_args(args, recorded_force=bool(recorded.forces), metadata=metadata), []


def _write_stress_strain(staged, load, area_mm2, frames, times, eng, names, *, title):
    """Write ``STRESS_FILES`` into ``staged``; returns what ``session.json`` says of them."""
    from livedic.dic.strain.extensometer import AXIAL
    from livedic.stream.stages.stress import (force_coverage_notes, plot_stress_strain, stress_strain_rows,
                                       stress_strain_table)
    times = np.asarray(times, dtype=np.float64)
    force = _force_on_frames(load, frames, times)
    table = stress_strain_table(frames, times, force, eng[:, list(names).index(AXIAL)], area_mm2)
    staged["stress_strain.csv"].write(stress_strain_rows(table, csv_rows))
    plot_stress_strain(staged["stress_strain.png"].handle, table, title=title)
    return {"frames_with_force": int(np.isfinite(force).sum()), "uniform_frame_row": table.uniform_frame,
            "uniform_frame": int(table.frame[table.uniform_frame]) if table.uniform_frame >= 0 else -1,
            "notes": force_coverage_notes(table.frame, table.time_s, table.force_N, table.eng_strain)}


def axial_series(path, strain=None):
    """The ``axial`` extensometer of a recording, frame by frame, recomputed as ``export_recording`` does.

    Returns
    -------
    dict
        ``metadata``, ``frames`` (indices), ``time_s`` (since the first frame with results),
        ``eng_strain`` (NaN where not read), ``transverse_eng_strain`` (the ``transverse``
        extensometer's, all NaN without one: ``has_transverse``), ``l0_px``, ``scale`` (px/mm or None), ``truncated``,
        ``notes``, ``strain`` (the stage's one-line description).

    Raises
    ------
    ValueError
        Not a recording, a bad strain setting, or no ``axial`` extensometer (one line).
    """
    from livedic.acquire.recording.reader import Recording
    from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE
    from livedic.stream.stages.strain import StrainConfig
    with reader_notes() as notes:
        recording = Recording(os.fspath(path))
        metadata, session_note = session_or_note(recording)
        if session_note:
            notes.append(session_note)
        p0_id, _ = p0_point_id(metadata)
        config = StrainConfig.from_metadata(metadata, **(strain or {}))
        results = recording.results()
        first = next(results, None)
        stage = strain_stage(metadata, first, p0_id, strain) if first is not None else None
        names = stage.placed.names if stage is not None else tuple(e.name for e in config.extensometers)
        if AXIAL not in names:
            raise ValueError(f"the stress-strain curve needs an '{AXIAL}' extensometer, and this recording has "
                             f"{'only ' + ', '.join(names) if names else 'none'}: add --gauge-length L[,W] "
                             f"(or --extensometer {AXIAL}=x1,y1,x2,y2)")
        column = list(names).index(AXIAL)
        across = list(names).index(TRANSVERSE) if TRANSVERSE in names else None
        frames, times, eng, transverse = [], [], [], []
        t0 = None
        for result in _chain(first, results):
            if np.array_equal(result.point_id, first.point_id):
                _, readings = stage.compute(result.u, result.v, result.ok)
            else:
                readings = _lost_readings(stage.placed)
            t0 = int(result.timestamp_ns) if t0 is None else t0
            frames.append(int(result.frame_index))
            times.append((int(result.timestamp_ns) - t0) / 1e9)
            eng.append(float(readings.eng_strain[column]))
            transverse.append(float(readings.eng_strain[across]) if across is not None else math.nan)
        truncated = recording.info.truncated
    l0 = stage.extensometers[column].length_px if stage is not None else math.nan
    return {"metadata": metadata, "frames": np.asarray(frames, dtype=np.int64),
            "time_s": np.asarray(times, dtype=np.float64), "eng_strain": np.asarray(eng, dtype=np.float64),
            "transverse_eng_strain": np.asarray(transverse, dtype=np.float64), "has_transverse": across is not None,
            "l0_px": float(l0), "scale": config.scale, "truncated": truncated, "notes": list(notes),
            "strain": stage.describe() if stage is not None else ""}


def _chain(first, rest):
    """``first`` (when not None) then the rest of the results."""
    if first is None:
        return
    yield first
    yield from rest


def _strain_settings(stage, config, overrides):
    """What the strain columns and the extensometers were computed with, for ``session.json``."""
    settings = {"recomputed_from": "the recorded displacements", "measure": config.measure, "window": config.window,
                "scale_px_per_mm": config.scale, "overridden": sorted(overrides or {})}
    if stage is not None:
        settings.update(step_px=stage.windows.step, subset_px=stage.windows.subset, vsg_px=stage.vsg_px,
                        extensometers=[{"name": e.name, "x1": e.x1, "y1": e.y1, "x2": e.x2, "y2": e.y2,
                                        "L0_px": e.length_px} for e in stage.extensometers])
    return settings


def plural(count, word):
    """``"1 frame"``, ``"3 frames"``."""
    return f"{count} {word}" + ("" if count == 1 else "s")
