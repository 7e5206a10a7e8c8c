"""``csv:FILE``: force exported by the testing machine's software (header ``time_s,force_N``), on session
time; and ``_KnownSamples``, what a force known in full before the session shares (a file, the simulator's law).
"""

from __future__ import annotations

import csv
import math
import os
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.acquire.force.source import (CSV_HEADER, DEFAULT_MAX_GAP_S, TIME_BASE_SESSION, LoadError, LoadSource,
                                          interpolate_force)

__all__ = ["CsvLoad", "read_force_csv", "csv_max_gap_s"]


def read_force_csv(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """``(time_s, force_N)`` arrays from a CSV with header ``time_s,force_N`` (more columns allowed after).

    Raises
    ------
    LoadError
        Missing or unreadable file, wrong header, a value that is not a finite number, time not
        strictly increasing, or no samples: one line naming the file and line.
    """
    try:
        handle = open(path, newline="", encoding="utf-8-sig")
    except OSError as error:
        raise LoadError(f"load file {path}: cannot be read ({error.strerror or error}); "
                        f"expected a CSV with header time_s,force_N") from None
    times: list[float] = []
    forces: list[float] = []
    with handle:
        try:
            rows = csv.reader(handle)
            header = next(rows, None)
            if header is None or tuple(cell.strip() for cell in header[:2]) != CSV_HEADER:
                raise LoadError(f"load file {path} line 1: header must start with time_s,force_N, "
                                f"found {','.join(header or [])[:60]!r}")
            for row in rows:
                line = rows.line_num
                if not any(cell.strip() for cell in row):
                    continue                      # blank line (a trailing newline, a spreadsheet's empty row)
                if len(row) < 2:
                    raise LoadError(f"load file {path} line {line}: expected time_s,force_N, found {','.join(row)[:60]!r}")
                time_s, force_n = (_finite(path, line, name, cell) for name, cell in zip(CSV_HEADER, row[:2]))
                if times and time_s <= times[-1]:
                    raise LoadError(f"load file {path} line {line}: time_s {time_s:g} is not after "
                                    f"the previous {times[-1]:g} (must increase strictly)")
                times.append(time_s)
                forces.append(force_n)
        except UnicodeDecodeError:
            raise LoadError(f"load file {path}: not a text CSV (expected UTF-8 with header time_s,force_N)") from None
        except csv.Error as error:
            raise LoadError(f"load file {path} line {rows.line_num}: {error}") from None
    if not times:
        raise LoadError(f"load file {path}: no samples after the header time_s,force_N")
    return np.asarray(times, np.float64), np.asarray(forces, np.float64)


def _finite(path: str | os.PathLike[str], line: int, name: str, cell: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise LoadError(f"load file {path} line {line}: {name} {cell.strip()[:30]!r} is not a finite number")
    return value


def csv_max_gap_s(time_s: np.ndarray) -> float:
    """Default gap that is a stall in a file: ``DEFAULT_MAX_GAP_S`` or 5 median sample intervals if longer.

    Why: a slow export (1 Hz) is not a stall at every sample, yet a hole of several intervals is.
    """
    if time_s.size < 2:
        return DEFAULT_MAX_GAP_S
    return max(DEFAULT_MAX_GAP_S, 5.0 * float(np.median(np.diff(time_s))))


class _KnownSamples(LoadSource):
    """A force known in full before the session (a file, the simulator's law), on session time.

    Read in place: the per-frame look-ups (``force_at``, ``last_sample_time_s``) copy nothing, whatever
    the length of the file (a 1 kHz log of a long test holds 10^5-10^6 samples).
    """

    time_base = TIME_BASE_SESSION
    _time = np.zeros(0)
    _force = np.zeros(0)

    def samples(self) -> tuple[np.ndarray, np.ndarray]:
        return self._time.copy(), self._force.copy()

    def force_at(self, times_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        return interpolate_force(self._time, self._force, times_s, self.max_gap_s)

    @property
    def last_sample_time_s(self) -> float:
        return float(self._time[-1]) if self._time.size else math.nan


class CsvLoad(_KnownSamples):
    """Force from a CSV file; times are seconds since the session's first frame, plus ``offset_s``."""

    def __init__(self, path: str | os.PathLike[str], *, offset_s: float = 0.0, max_gap_s: float | None = None,
                 uri: str | None = None) -> None:
        self.path = str(path)
        self.uri = uri or f"csv:{self.path}"
        self.offset_s = float(offset_s)
        time_s, self._force = read_force_csv(self.path)
        self._time = time_s + self.offset_s
        self.max_gap_s = float(max_gap_s) if max_gap_s is not None else csv_max_gap_s(time_s)

    @property
    def settings(self) -> dict[str, Any]:
        return {**super().settings, "offset_s": self.offset_s}
