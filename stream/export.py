"""``livedic export``: a recording's results as CSV files anyone can open.

``livedic export FILE.mcap -o DIR`` writes four files into DIR (created if missing):

``p0_trace.csv``
    The traced point P0 over time, one row per frame with results:
    ``frame,timestamp_ns,time_s,x,y,u,v,zncc,ok``. ``time_s`` is seconds since the
    first frame with results (the reference frame). P0's id is read from the session
    metadata (``p0_id`` when present, else the ``point_ids`` note, "P0 is point 0").
``fields.csv``
    Every frame, every point, long format:
    ``frame,timestamp_ns,point_id,x,y,u,v,zncc,ok`` then the extras the recording holds
    (``status``, ``ux``, ``uy``, ``vx``, ``vy``, ``iterations``) - the same columns as
    ``livedic replay``, so the two files can be compared line by line.
``events.csv``
    ``time,kind,level,message,timestamp_ns``: ``time`` in seconds on the same clock as
    ``p0_trace.csv`` (``timestamp_ns`` is the raw frame clock).
``session.json``
    The session metadata (method, parameters, source, ROI, ...), plus a
    ``livedic.export`` entry saying where the files came from and whether the
    recording was complete.

Numbers are written at full precision (the shortest text that reads back as the
same float64), NaN as ``nan``, ``ok`` as 1/0: a value read back from these files is
bit-for-bit the recorded one.

Every file is written under a temporary name and all four are renamed into place
only when all are complete, so an error or Ctrl-C never leaves a half-written
file. Existing files are not replaced unless ``--overwrite``. A truncated recording
(crash, kill, disk full) exports what can be recovered and says so in a note; the
``truncated`` flag is the reader's (``RecordingInfo.truncated``), never read from
the note's text.

The helpers here (CSV formatting, atomic files, reader notes, P0 lookup) are also
used by ``stream.replay``.
"""

import csv
import io
import logging
import math
import os
import re
import sys
from contextlib import contextmanager
from datetime import datetime, timezone

import numpy as np

from livedic.stream.csv_output import AtomicFile, OutputError, check_output_file, check_output_folder, json_text

LEADING_COLUMNS = ("frame", "timestamp_ns", "point_id", "x", "y", "u", "v", "zncc", "ok")
EXTRA_COLUMNS = ("status", "ux", "uy", "vx", "vy", "iterations")
P0_COLUMNS = ("frame", "timestamp_ns", "time_s", "x", "y", "u", "v", "zncc", "ok")
EVENT_COLUMNS = ("time", "kind", "level", "message", "timestamp_ns")
EXPORT_FILES = ("p0_trace.csv", "fields.csv", "events.csv", "session.json")
EXPORT_KEY = "livedic.export"

_READER_LOGGER = "livedic.acquire.mcap_replay"


# ----------------------------------------------------------------------------- CSV text

def _text(values, n):
    """``values`` (scalar or array of length n) as a list of n strings, full precision."""
    array = np.asarray(values)
    if array.ndim == 0:
        return [_scalar_text(array.item())] * n
    if array.dtype == bool:
        return np.where(array, "1", "0").tolist()
    if array.dtype.kind in "OUS":
        return [_scalar_text(value) for value in array.tolist()]
    if array.dtype.kind in "iu":
        return array.astype(str).tolist()
    # numpy's float -> str cast is the shortest repr that reads back as the same double.
    return array.astype(np.float64).astype(str).tolist()


def _scalar_text(value):
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def csv_rows(columns, n):
    """CSV lines (no header, each ending in a newline) for ``columns``: ordered name -> scalar or (n,) array."""
    if n == 0:
        return ""
    texts = [_text(values, n) for values in columns.values()]
    return "\n".join(map(",".join, zip(*texts))) + "\n"


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


def check_output_csv(output, recording):
    """Refuse an output path that would destroy the recording or cannot be written (``OutputError``)."""
    if output in (None, "-"):
        return
    if os.path.isdir(output):
        raise OutputError(f"-o {output} is a folder: give a file name, e.g. {os.path.join(output, 'replay.csv')}")
    if output.lower().endswith(".mcap"):
        raise OutputError(f"-o {output} ends in .mcap: the output is CSV (e.g. replay.csv); "
                          f"recordings are never written over")
    if os.path.exists(output) and os.path.exists(recording) and os.path.samefile(output, recording):
        raise OutputError(f"-o {output} is the recording itself: choose another file")
    check_output_file(output, "-o")


# ----------------------------------------------------------------------------- recording helpers

@contextmanager
def reader_notes():
    """Collect the notes ``acquire.mcap_replay`` logs (truncated file ...) instead of printing them raw.

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
    from livedic.acquire.mcap_replay import NoSessionMetadata
    try:
        return recording.session(), ""
    except NoSessionMetadata as missing:
        return {}, str(missing)


def read_session_or_note(path):
    """``session_or_note`` of the recording at ``path`` (``RecordingError`` if it is not one)."""
    from livedic.acquire.mcap_replay import Recording
    return session_or_note(Recording(path))


def say(message):
    print(f"livedic: {message}", file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- export

def export_recording(path, directory, *, overwrite=False):
    """Write ``EXPORT_FILES`` for recording ``path`` into ``directory`` (see module notes).

    Returns
    -------
    dict
        ``directory``, ``files`` (paths), ``frames`` (frames with results),
        ``points`` (points in the first frame), ``events``, ``p0_id``, ``p0_rows``,
        ``truncated``, ``notes`` (list of lines).

    Raises
    ------
    ValueError
        ``directory`` is a file, a target exists without ``overwrite``, or the
        recording is missing, not MCAP, not livedic, or corrupt (``RecordingError``).
    """
    from livedic.acquire.mcap_replay import Recording

    path, directory = os.fspath(path), os.fspath(directory)
    check_output_folder(directory, "-o")
    targets = {name: os.path.join(directory, name) for name in EXPORT_FILES}
    existing = [name for name, target in targets.items() if os.path.lexists(target)]
    if existing and not overwrite:
        raise ValueError(f"{directory} already holds {', '.join(existing)}: pass --overwrite to replace "
                         f"{'it' if len(existing) == 1 else 'them'}, or choose another folder")
    with reader_notes() as notes:
        recording = Recording(path)                             # checks the file before DIR is made
        metadata, session_note = session_or_note(recording)
        if session_note:
            notes.append(session_note)
        p0_id, p0_how = p0_point_id(metadata)
        created = not os.path.isdir(directory)
        os.makedirs(directory, exist_ok=True)
        staged = {}
        try:
            for name, target in targets.items():
                staged[name] = StagedFile(target)
            fields, trace = staged["fields.csv"], staged["p0_trace.csv"]
            fields_header = None
            trace.write(",".join(P0_COLUMNS) + "\n")
            frames = p0_rows = points = 0
            p0_missing = 0
            t0 = None
            extras_seen = None
            for result in recording.results():
                extras = {name: getattr(result, name) for name in EXTRA_COLUMNS
                          if getattr(result, name) is not None and len(getattr(result, name)) == len(result.u)}
                if fields_header is None:
                    extras_seen = [name for name in EXTRA_COLUMNS if name in extras]
                    fields_header = list(LEADING_COLUMNS) + extras_seen
                    fields.write(",".join(fields_header) + "\n")
                    points = len(result.u)
                n = len(result.u)
                for name in extras_seen:          # a frame without an extra the first one had: blank cells
                    extras.setdefault(name, np.full(n, "", dtype=object))
                extras = {name: extras[name] for name in extras_seen}
                columns = result_columns(result.frame_index, result.timestamp_ns, result.point_id, result.x,
                                         result.y, result.u, result.v, result.zncc, result.ok, extras)
                fields.write(csv_rows(columns, n))
                if t0 is None:
                    t0 = int(result.timestamp_ns)
                where = np.flatnonzero(result.point_id == p0_id)
                if where.size:
                    k = int(where[0])
                    trace.write(csv_rows({
                        "frame": int(result.frame_index), "timestamp_ns": int(result.timestamp_ns),
                        "time_s": (int(result.timestamp_ns) - t0) / 1e9, "x": float(result.x[k]),
                        "y": float(result.y[k]), "u": float(result.u[k]), "v": float(result.v[k]),
                        "zncc": float(result.zncc[k]), "ok": bool(result.ok[k])}, 1))
                    p0_rows += 1
                else:
                    p0_missing += 1
                frames += 1
            if fields_header is None:
                fields.write(",".join(LEADING_COLUMNS) + "\n")
            events = recording.events()
            if t0 is None and events:
                t0 = min(event.timestamp_ns for event in events)
            buffer = io.StringIO()
            writer = csv.writer(buffer, lineterminator="\n")
            writer.writerow(EVENT_COLUMNS)
            for event in events:
                writer.writerow([_scalar_text((event.timestamp_ns - (t0 or 0)) / 1e9), event.kind, event.level,
                                 " ".join(str(event.message).splitlines()), event.timestamp_ns])
            staged["events.csv"].write(buffer.getvalue())
            if frames and p0_missing:
                notes.append(f"P0 (point {p0_id}) is missing from {p0_missing} of {frames} frames' results")
            if frames == 0:
                notes.append(f"{path} holds no tracking results (/dic/results): fields.csv and p0_trace.csv "
                             f"have headers only")
            truncated = recording.info.truncated
            session = dict(metadata)
            session[EXPORT_KEY] = {
                "source": os.path.abspath(path), "exported_at": datetime.now(timezone.utc).isoformat(),
                "frames_with_results": frames, "points": points, "events": len(events),
                "p0_id": p0_id, "p0_id_from": p0_how, "time_origin_ns": t0,
                "truncated": truncated, "notes": list(notes)}
            staged["session.json"].write(json_text(session))
            for name in EXPORT_FILES:
                staged[name].commit()
        except BaseException:
            for item in staged.values():
                item.discard()
            if created:
                try:
                    os.rmdir(directory)          # only if still empty
                except OSError:
                    pass
            raise
    return {"directory": directory, "files": [targets[name] for name in EXPORT_FILES], "frames": frames,
            "points": points, "events": len(events), "p0_id": p0_id, "p0_rows": p0_rows,
            "truncated": truncated, "notes": list(notes)}


def _plural(count, word):
    return f"{count} {word}" + ("" if count == 1 else "s")


def export_command(args):
    """``livedic export FILE.mcap -o DIR [--overwrite]``; returns the exit code."""
    summary = export_recording(args.recording, args.output, overwrite=args.overwrite)
    for note in summary["notes"]:
        say(f"note: {note}")
    state = " (what could be recovered from the truncated recording)" if summary["truncated"] else ""
    say(f"exported {summary['frames']} frames x {summary['points']} points{state}, P0 = point "
        f"{summary['p0_id']} ({summary['p0_rows']} rows), {_plural(summary['events'], 'event')} "
        f"to {summary['directory']}/ "
        f"({', '.join(EXPORT_FILES)})")
    return 0
