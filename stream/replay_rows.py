"""The CSV lines of ``livedic replay``: one frame's rows, formatted wherever the frame was measured.

The sequential replay formats them in its own process; the parallel one
(``stream.parallel_replay``) on the worker that measured the frame, as formatting
floats at full precision costs ~20 us a point (200 ms a frame at 10,000 points, more
than tracking it), which in the replaying process alone would bound the rate however
many workers there are. One function either way, so the files are the same.
"""

import numpy as np

from livedic.stream.export import EXTRA_COLUMNS, LEADING_COLUMNS, STRAIN_COLUMNS, csv_rows, result_columns

_GRADIENTS = ("ux", "uy", "vx", "vy", "iterations")


def frame_rows(frame_index, timestamp_ns, point_ids, measurement, strain):
    """(header, lines) of one frame: the replay CSV's column names for ``measurement`` and its rows.

    Parameters
    ----------
    frame_index, timestamp_ns : int
    point_ids : ndarray (N,)
    measurement : dic.result.Measurement
        Its ``status`` and, when it has them, ``ux, uy, vx, vy, iterations`` become columns.
    strain : dic.strain.StrainField
        ``exx, eyy, exy`` at the points (recomputed on the replayed displacements).

    Returns
    -------
    header : list of str
        ``LEADING_COLUMNS``, then the extras in ``EXTRA_COLUMNS`` order, then ``STRAIN_COLUMNS``.
    lines : str
        One line per point, each ending in a newline (numbers at full precision).
    """
    m = measurement
    extras = {"status": np.asarray(m.status, dtype=np.int64)}
    for name in _GRADIENTS:
        value = getattr(m, name)
        if value is not None:
            extras[name] = value
    header = list(LEADING_COLUMNS) + [name for name in EXTRA_COLUMNS if name in extras] + list(STRAIN_COLUMNS)
    columns = result_columns(frame_index, timestamp_ns, point_ids, m.x, m.y, m.u, m.v, m.zncc, m.ok, extras)
    columns.update(exx=strain.exx, eyy=strain.eyy, exy=strain.exy)
    return header, csv_rows(columns, len(m.u))


FORCE_COLUMNS = ("force_N", "eng_stress_MPa")


def with_force_columns(header, lines, force_N, stress_MPa):
    """``frame_rows``' (header, lines) with the frame's force and engineering stress appended to every row.

    ``livedic replay --load``: one value per frame, repeated on its points' rows (the long format of
    the other per-frame columns, frame and timestamp_ns); ``nan`` where unknown (no sample around the
    frame), as the other columns write a missing number.
    """
    cells = ",".join(_cell(value) for value in (force_N, stress_MPa))
    return list(header) + list(FORCE_COLUMNS), lines.replace("\n", f",{cells}\n")


def _cell(value):
    return "nan" if value is None or not np.isfinite(value) else repr(float(value))
