"""The points a session tracks: read from a CSV, or a grid over the ROI, with P0 first; and their cost.

``build_points`` places them on the first frame (``livedic run``, ``replay``);
``check_point_count`` refuses, before anything is opened, more points than a
live session can take (``--max-points``), saying what they would cost.
"""

import csv

import numpy as np

from livedic.stream.config import UsageError


def read_points_csv(path):
    """Points from a CSV whose header names columns x and y (other columns ignored); (N, 2) float64."""
    return read_points_table(path)[0]


def read_points_table(path):
    """Points and the file's other columns from a CSV whose header names columns x and y.

    Returns
    -------
    xy : ndarray, shape (N, 2), float64
    extras : dict
        Every other column of the header, in file order: name (as written) -> list of N strings
        (empty where a line is short).

    Raises
    ------
    UsageError
        A missing, unreadable or empty file, no x and y in the header, a line whose x or y is
        not a number, or NaN/infinite coordinates.
    """
    try:
        with open(path, newline="") as handle:
            rows = [row for row in csv.reader(handle) if any(field.strip() for field in row)]
    except FileNotFoundError:
        raise UsageError(f"points file {path} does not exist") from None
    except (UnicodeDecodeError, IsADirectoryError, PermissionError, csv.Error) as error:
        raise UsageError(f"cannot read points file {path}: {error.__class__.__name__}") from None
    if not rows:
        raise UsageError(f"points file {path} is empty: it needs a header line 'x,y' and one point per line")
    names = [name.strip() for name in rows[0]]
    header = [name.lower() for name in names]
    if "x" not in header or "y" not in header:
        raise UsageError(f"points file {path} has header {','.join(rows[0])!r}: it must name columns x and y")
    ix, iy = header.index("x"), header.index("y")
    extra_columns = [(k, name) for k, name in enumerate(names) if k not in (ix, iy) and name]
    points = []
    extras = {name: [] for _, name in extra_columns}
    for number, fields in enumerate(rows[1:], start=2):
        try:
            points.append((float(fields[ix]), float(fields[iy])))
        except (ValueError, IndexError):
            raise UsageError(f"points file {path}, line {number}: {','.join(fields)!r} is not a number pair "
                             f"x,y") from None
        for k, name in extra_columns:
            extras[name].append(fields[k].strip() if k < len(fields) else "")
    if not points:
        raise UsageError(f"points file {path} has a header but no points")
    xy = np.array(points)
    if not np.all(np.isfinite(xy)):
        raise UsageError(f"points file {path} contains NaN or infinite coordinates")
    return xy, extras


def build_points(shape, *, roi, step, n_points, subset, p0=None, points=None):
    """Tracked points with P0 first: ``(points (N, 2), roi used, step used)``.

    P0 is ``p0`` or the ROI centre, snapped to a pixel; a grid point on the same
    pixel is not repeated.

    Raises
    ------
    ValueError
        An ROI beyond the image, given points or P0 outside it (one line each).
    """
    from livedic.dic.tracking import grid_in_roi, step_for_count
    height, width = shape
    if roi is None:
        roi = (0, 0, width, height)
    x, y, w, h = roi
    if x < 0 or y < 0 or x + w > width or y + h > height:
        raise ValueError(f"ROI {x},{y},{w},{h} extends beyond the {width}x{height} image: "
                         f"give X,Y,W,H with X+W <= {width} and Y+H <= {height}")
    if points is not None:
        xy = np.asarray(points, dtype=np.float64)
        outside = (xy[:, 0] < 0) | (xy[:, 1] < 0) | (xy[:, 0] > width - 1) | (xy[:, 1] > height - 1)
        if outside.any():
            bad = xy[np.argmax(outside)]
            raise ValueError(f"{int(outside.sum())} of the given points lie outside the {width}x{height} image "
                             f"(first: {bad[0]:g},{bad[1]:g}): keep 0 <= x <= {width - 1} and 0 <= y <= {height - 1}")
    if points is None:
        if step is None:
            step = step_for_count(roi, n_points, subset)
        grid = grid_in_roi(shape, roi, step, subset)
    else:
        grid = np.asarray(points, dtype=np.float64)
    if p0 is None:
        p0 = (x + (w - 1) / 2.0, y + (h - 1) / 2.0)
    p0 = np.floor(np.asarray(p0, dtype=np.float64) + 0.5)
    if not (0 <= p0[0] < width and 0 <= p0[1] < height):
        raise ValueError(f"P0 ({p0[0]:g}, {p0[1]:g}) is outside the {width}x{height} image")
    same = np.all(np.floor(grid + 0.5) == p0[None, :], axis=1)
    grid = grid[~same]
    return np.vstack([p0[None, :], grid]), tuple(int(v) for v in roi), step


# Tracker memory per point, measured with IC-GN and the seeded search on 1 MP: 5,184 points 31 MB,
# 40,401 points 280 MB (reference subset, gradients, Hessian and per-point state): ~7 KB.
TRACKER_BYTES_PER_POINT = 7_000
# One point's share of a recorded result set: x, y, u, v, zncc, ux, uy, vx, vy (float64), point id,
# status, iterations and ok.
RESULT_BYTES_PER_POINT = 90


def _size(n_bytes):
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def check_point_count(n_points, max_points, *, how, frames=None, recording=True):
    """ValueError (one line, with the cost) when ``n_points`` is more than ``max_points``."""
    if n_points <= max_points:
        return
    cost = f"about {_size(n_points * TRACKER_BYTES_PER_POINT)} of memory"
    if frames and recording:
        cost += f" and {_size(n_points * RESULT_BYTES_PER_POINT * frames)} of results recorded over {frames} frames"
    raise ValueError(f"{how} gives {n_points:,} points, more than livedic run tracks live (--max-points "
                     f"{max_points:,}; {cost}, and frames are dropped when tracking takes longer than a frame "
                     f"period): use a larger --step, fewer --n-points or a smaller --roi, or raise --max-points")
