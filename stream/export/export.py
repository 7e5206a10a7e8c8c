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

The parts live beside this module: ``columns`` (the CSV columns and files), ``notes`` (the reader's notes,
the session metadata), ``recomputed_strain`` (strain and extensometers from the recorded displacements),
``force`` (the machine's force and the stress-strain files), ``stop`` (Ctrl-C and SIGTERM); ``livedic
replay`` uses the first two.
"""

import csv
import io
import os
from datetime import datetime, timezone

import numpy as np

from livedic.acquire.atomic_file import atomic_files
from livedic.stream.output.files import check_output_folder, json_text, write_text_atomic
from livedic.stream.output.csv_text import csv_rows, scalar_text
from livedic.stream.export.field_maps import COLOUR_MAP
from livedic.stream.export.field_options import NO_FIELDS, PVD_FILE, VIDEO_FOURCC, ColourRanges, quantities, video_name
from livedic.stream.export.field_writer import FieldWriter, RecordedImages, remove_stale
from livedic.stream.export.columns import (BINARY_FILES, EVENT_COLUMNS, EXPORT_FILES, EXPORT_KEY, EXTENSOMETER_COLUMNS,
                                          EXTRA_COLUMNS, LEADING_COLUMNS, P0_COLUMNS, STRAIN_COLUMNS, STRESS_FILES,
                                          extensometer_columns, result_columns)
from livedic.stream.export.force import RecordedForce, _force_label, _open_stress_load, _write_stress_strain
from livedic.stream.export.notes import plural, reader_notes, session_or_note
from livedic.stream.export.recomputed_strain import (_chain, _lost_readings, _strain_settings, p0_point_id,
                                                     plot_extensometers, strain_stage)
from livedic.stream.export.stop import _stopped_in
# Re-exported: stream.cli's export, replay and report commands name them as export's.
from livedic.stream.export.force import stress_from_args  # noqa: F401
from livedic.stream.export.notes import say  # noqa: F401
from livedic.stream.export.stop import ExportStopped, StopSignals  # noqa: F401


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
