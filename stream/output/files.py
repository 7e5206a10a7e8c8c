"""Output files of livedic: checked before any work starts, written atomically, never half-written.

Every file livedic writes for the user (``measure -o``, ``replay -o``, ``export -o``,
``run --summary-json``) goes through ``AtomicFile``: the text is written to a
temporary file beside the target and renamed into place when complete, with the
permissions a plain ``open(path, "w")`` would give (``0666 & ~umask``), so an
error or an interruption never leaves a partial file and all commands create
files alike.

``check_output_file`` and ``check_output_folder`` say, before a session or a
measurement starts, whether an output can be written at all (a missing or
read-only folder, a folder where a file is wanted, a file where a folder is
wanted): the problem is an ``OutputError`` (a ``ValueError``, so the command
line turns it into one line and exit code 2) instead of an ``OSError`` after
minutes of work.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import sys
import tempfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from livedic.acquire.atomic_file import TEMP_PREFIX as _TEMP_PREFIX
from livedic.acquire.atomic_file import AtomicFile, OutputError, current_umask
from livedic.acquire.recording.metadata import json_default
from livedic.stream.output.csv_text import csv_rows

__all__ = ["AtomicFile", "OutputError", "check_output_file", "check_output_folder", "current_umask", "json_text",
           "write_csv", "write_text_atomic"]


# ----------------------------------------------------------------------------- checks before the work

def _nearest_existing(path):
    """``path`` or the nearest ancestor of it that exists (absolute)."""
    current = os.path.abspath(path)
    while not os.path.lexists(current):
        parent = os.path.dirname(current)
        if parent == current:
            break
        current = parent
    return current


def _probe_folder(folder, what, path):
    """OutputError unless a file can be created in the existing folder ``folder``.

    A real file is created and removed: permission bits alone do not tell (root
    ignores them, a read-only mount or a full quota does not show in them).
    """
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {what} {path}: {folder} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=_TEMP_PREFIX, suffix=".probe", dir=folder)
    except PermissionError:
        raise OutputError(f"cannot write {what} {path}: folder {folder} is not writable (permission denied); "
                          f"choose another folder") from None
    except OSError as error:
        raise OutputError(f"cannot write {what} {path}: folder {folder} is not writable "
                          f"({error.strerror or error}); choose another folder") from None
    os.close(fd)
    os.unlink(probe)


def check_output_file(path: str | os.PathLike[str], what: str, *, create_folders: bool = False) -> None:
    """Raise ``OutputError`` unless ``path`` can be written as a (new or replaced) file.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    what : str
        How the user named it, for the message (e.g. ``"-o"``, ``"--summary-json"``).
    create_folders : bool
        The writer creates missing folders (then the nearest existing one must be writable).
    """
    path = os.fspath(path)
    if os.path.isdir(path):
        raise OutputError(f"{what} {path} is a folder: give a file name, e.g. "
                          f"{os.path.join(path, _example_name(what))}")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.lexists(folder):
        if not create_folders:
            raise OutputError(f"cannot write {what} {path}: folder {folder} does not exist")
        _probe_folder(_nearest_existing(folder), what, path)
        return
    _probe_folder(folder, what, path)
    if os.path.lexists(path) and not os.access(path, os.W_OK):
        # os.replace would succeed (it needs the folder only), but replacing a file the
        # user protected is not what they asked for.
        raise OutputError(f"cannot write {what} {path}: the file is read-only")


def check_output_folder(path: str | os.PathLike[str], what: str) -> None:
    """Raise ``OutputError`` unless ``path`` is (or can be created as) a folder that files can be written in."""
    path = os.fspath(path)
    if os.path.lexists(path) and not os.path.isdir(path):
        raise OutputError(f"{what} {path} is an existing file: give a folder (it is created if missing)")
    _probe_folder(_nearest_existing(path), what, path)


def _example_name(what):
    return {"--summary-json": "summary.json", "--record": "session.mcap", "--viewer save": "session.rrd"}.get(
        what, "out.csv")


# ----------------------------------------------------------------------------- atomic files

def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` through an ``AtomicFile``."""
    with AtomicFile(path) as out:
        out.write(text)
        out.commit()


# ----------------------------------------------------------------------------- JSON

def json_text(value: object, *, indent: int = 2) -> str:
    """``value`` as strict JSON text: NaN and infinities become ``null`` (JSON has no NaN),
    numpy scalars and arrays become numbers and lists, anything else unknown its ``str``."""
    return json.dumps(_json_ready(value), indent=indent, allow_nan=False) + "\n"


def _json_ready(value):
    if isinstance(value, dict):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(item) for item in value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return _json_ready(json_default(value))      # numpy values, paths ...: the format's one conversion


# ----------------------------------------------------------------------------- CSV tables

def write_csv(path: str | os.PathLike[str] | None, columns: Mapping[str, Any]) -> None:
    """Write ``columns`` (ordered name -> 1-D array) as CSV to ``path``, or stdout when path is None/'-'.

    Numbers in the format of every livedic CSV (``stream.output.csv_text``: full precision, ``nan``,
    ``inf``), booleans 1/0, integers as they are, text (object or string arrays) quoted where CSV needs
    it, as the header. The file is written through ``AtomicFile``.
    """
    names = list(columns)
    arrays = [np.asarray(columns[name]) for name in names]
    n = len(arrays[0]) if arrays else 0
    cells = {name: np.array([_quoted(value) for value in array.tolist()], dtype=object)
             if array.dtype.kind in "OUS" else array for name, array in zip(names, arrays)}
    text = ",".join(_quoted(name) for name in names) + "\n" + csv_rows(cells, n)
    if path in (None, "-"):
        sys.stdout.write(text)
        return
    write_text_atomic(path, text)


def _quoted(text):
    text = str(text)
    if any(c in text for c in ',"\n\r'):
        # csv quotes a line break only when it is part of the line terminator, so one is given and cut off
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\r\n").writerow([text])
        return buffer.getvalue()[:-2]
    return text
