"""Writing result tables as CSV without ever leaving a half-written file."""

import os
import sys
import tempfile

import numpy as np


def write_csv(path, columns):
    """Write ``columns`` (ordered name -> 1-D array) as CSV to ``path``, or stdout when path is None/'-'.

    The file is written to a temporary name beside ``path`` and renamed into
    place, so an error or interruption never leaves a partial file.
    """
    names = list(columns)
    arrays = [np.asarray(columns[name]) for name in names]
    lines = [",".join(names)]
    formatters = [_formatter(a) for a in arrays]
    for row in range(len(arrays[0]) if arrays else 0):
        lines.append(",".join(fmt(a[row]) for fmt, a in zip(formatters, arrays)))
    text = "\n".join(lines) + "\n"
    if path in (None, "-"):
        sys.stdout.write(text)
        return
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise ValueError(f"cannot write {path}: folder {directory} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=".livedic-", suffix=".csv", dir=directory)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _formatter(array):
    if array.dtype == bool:
        return lambda value: "1" if value else "0"
    if array.dtype.kind in "iu":
        return lambda value: str(int(value))
    return lambda value: "nan" if not np.isfinite(value) else f"{value:.6f}"
