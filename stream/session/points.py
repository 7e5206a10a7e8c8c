"""The points a session tracks: where they may go, where they are placed (P0 first), and their cost.

``place_points`` places them on the reference frame for ``livedic run``, ``replay``,
``preview`` and ``measure``: a grid over the region the user gave (``--roi`` as a
rectangle or a polygon, ``--mask FILE.png``, ``--exclude`` shapes; ``dic.region``)
or, without one, over the speckled specimen found in the image, or the points of a
CSV; no point whose subset reaches outside the region or into an exclusion.
``add_region_arguments`` declares those options once for every command.
``check_point_count`` refuses, before anything is opened, more points than a live
session can take (``--max-points``), saying what they would cost.
"""

from __future__ import annotations

import argparse
import csv
import enum
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from livedic.dic.bspline import INTERPOLATION_MARGIN
from livedic.dic.validation import check_subset
from livedic.dic.region import (Rectangle, Region, Specimen, bounding_box, find_specimen, grid_in_region,
                                placeable)
from livedic.stream.session.config import DEFAULT_MAX_POINTS, DEFAULT_POINTS
from livedic.stream.session.parsing import ROI_AUTO, ROI_FULL, UsageError
from livedic.stream.session.p0 import P0Choice, choose_p0

if TYPE_CHECKING:
    from livedic.stream.session.config import PointsConfig

# Around a found specimen's edge a subset keeps this many px more inside it: the edge is found to about
# a pixel, and a subset touching the edge's dark outline would see it move against the background.
SPECIMEN_MARGIN = 2


def read_points_csv(path: str | os.PathLike[str]) -> np.ndarray:
    """Points from a CSV whose header names columns x and y (other columns ignored); (N, 2) float64."""
    return read_points_table(path)[0]


def read_points_table(path: str | os.PathLike[str]) -> tuple[np.ndarray, dict[str, list[str]]]:
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
    extras: dict[str, list[str]] = {name: [] for _, name in extra_columns}
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


def default_roi(source: object) -> tuple[int, ...] | None:
    """The source's suggested ROI (the simulator's gauge section), a replayed session's ROI, or None."""
    roi = getattr(source, "suggested_roi", None)
    if roi is not None:
        return tuple(int(v) for v in roi)
    session = getattr(source, "session", None)
    if isinstance(session, dict) and isinstance(session.get("roi"), (list, tuple)) and len(session["roi"]) == 4:
        return tuple(int(v) for v in session["roi"])
    return None


def add_region_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup, *, points: bool = True) -> None:
    """Declare ``--roi``, ``--mask``, ``--exclude`` (and ``--points`` when ``points``) on an argparse parser.

    Every command that places points (``run``, ``replay``, ``preview``, ``measure``) takes them from here.
    """
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--roi", metavar="REGION",
                       help="where the points go: X,Y,W,H (a rectangle), polygon:X1,Y1,X2,Y2,X3,Y3[,...], auto "
                            "(the speckled specimen found in the image) or full (the whole image). Default: the "
                            "simulator's gauge section, a recording's own region, else auto")
    if points:
        where.add_argument("--points", metavar="FILE.csv",
                           help="track these points (CSV with header x,y) instead of a grid")
    parser.add_argument("--mask", metavar="FILE.png",
                        help="an image of the camera's size, white on the specimen: points only where their whole "
                             "subset is white (with --roi: inside both)")
    parser.add_argument("--exclude", action="append", metavar="SHAPE",
                        help="leave out an area no subset may reach into (a hole, a clip, a marker): circle:X,Y,R, "
                             "rect:X,Y,W,H or polygon:X1,Y1,X2,Y2,X3,Y3[,...] (px; repeatable)")


def add_point_arguments(parser: argparse.ArgumentParser) -> None:
    """Declare the point options of ``livedic run`` and ``preview``: the region (``add_region_arguments``),
    ``--step``, ``--n-points``, ``--p0``, ``--max-points``."""
    add_region_arguments(parser)
    parser.add_argument("--step", type=int, metavar="S",
                        help="grid step in pixels (default: about --n-points points over the region)")
    parser.add_argument("--n-points", type=int, default=DEFAULT_POINTS, metavar="N",
                        help=f"points wanted when --step is not given (default {DEFAULT_POINTS})")
    parser.add_argument("--p0", metavar="X,Y",
                        help="the traced point P0 (default: the best-textured point near the region's centre, never "
                             "on a hole or background; a given P0 on weak texture is warned about)")
    parser.add_argument("--max-points", type=int, default=DEFAULT_MAX_POINTS, metavar="N",
                        help=f"refuse to start with more than N points (default {DEFAULT_MAX_POINTS:,}: about "
                             f"{DEFAULT_MAX_POINTS * 7 // 1000} MB of tracker memory and a few frames a second on one "
                             "core); raise it for slow tests on a big machine")


class PlacedBy(enum.Enum):
    """What decided where the points went."""
    GIVEN_REGION = "the given region"
    SOURCE = "the source's region"
    SPECIMEN = "the speckled specimen found in the image"
    WHOLE_IMAGE = "the whole image"
    POINTS = "the given points"


@dataclass(frozen=True)
class Placement:
    """The points on the reference frame and how they were placed (``place_points``).

    Attributes
    ----------
    points : ndarray (N, 2)
        (x, y) pixel centres, P0 first.
    p0 : stream.session.p0.P0Choice
        Where P0 is and why.
    step : int or None
        Grid step, px (None for given points).
    bounds : (x, y, w, h)
        The bounding box of the region where points may go (the session's "ROI").
    region : ndarray (H, W) of bool
        Where subsets may lie: the outline, mask and specimen, less the exclusions.
    placed_by : PlacedBy
    specimen : dic.region.Specimen or None
        The speckled area found (``--roi auto`` or by default).
    spec : dic.region.Region
        What the user gave (outline, mask, exclusions).
    dropped : int
        Given points left out because their subset reaches outside the region or into an exclusion.
    """
    points: np.ndarray = field(repr=False)
    p0: P0Choice
    step: int | None
    bounds: tuple
    region: np.ndarray = field(repr=False)
    placed_by: PlacedBy
    specimen: Specimen | None
    spec: Region
    dropped: int = 0

    def describe(self) -> str:
        """Where the points went and why, for the session's note."""
        how = {PlacedBy.GIVEN_REGION: self.spec.describe(),
               PlacedBy.SOURCE: f"the source's region {','.join(map(str, self.bounds))}",
               PlacedBy.SPECIMEN: self.specimen.describe() if self.specimen is not None else "",
               PlacedBy.WHOLE_IMAGE: "the whole image",
               PlacedBy.POINTS: "the given points"}[self.placed_by]
        if self.placed_by is not PlacedBy.GIVEN_REGION and self.spec.exclude:
            how += ", " + ", ".join(f"excluding {shape.describe()}" for shape in self.spec.exclude)
        text = f"{len(self.points)} points"
        if self.step is not None:
            text += f" every {self.step} px"
        text += f" over {how}"
        if self.dropped:
            text += f" ({self.dropped} given points left out: their subset reaches outside the region)"
        return text

    def as_metadata(self) -> dict:
        """The placement as the recording's session metadata holds it (``region`` key)."""
        meta = {"placed_by": self.placed_by.name.lower(), **self.spec.as_metadata(),
                "bounds": list(self.bounds), "area_px": int(self.region.sum()), "dropped_points": self.dropped}
        if self.specimen is not None:
            meta["specimen"] = {"share": round(self.specimen.share, 4), "pieces": self.specimen.pieces,
                                "separated": self.specimen.separated,
                                "texture_threshold": round(float(self.specimen.threshold), 6)}
        return meta


def _step_for(allowed: np.ndarray, n_points: int) -> int:
    """The grid step whose grid over ``allowed`` holds the number of points closest to ``n_points``."""
    area = int(allowed.sum())
    guess = max(int(np.sqrt(area / max(float(n_points), 1.0))), 1)
    best, best_error = guess, None
    for candidate in range(max(guess - 2, 1), guess + 3):
        error = abs(len(grid_in_region(allowed, candidate)) - n_points)
        if best_error is None or error < best_error:
            best, best_error = candidate, error
    return best


def where_points_go(image: np.ndarray, wanted: PointsConfig, *, subset: int, suggested_roi: tuple | None = None) -> tuple:
    """``(spec, region, allowed, placed_by, specimen)``: where subsets may lie, and the centres that keep them there.

    ``spec`` is the ``dic.region.Region`` applied (the user's, or the source's rectangle); ``region``
    the (H, W) pixels a subset may cover; ``allowed`` the pixel centres whose subset does
    (``dic.region.placeable``); ``placed_by`` a ``PlacedBy``; ``specimen`` the ``dic.region.Specimen``
    found, or None. The order of the rules is ``place_points``'s.
    """
    shape = image.shape[:2]
    check_subset(subset, shape)
    spec = wanted.region
    spec.check(shape)
    specimen = None
    margin = 0
    within = None
    if wanted.xy is not None:
        placed_by = PlacedBy.POINTS
    elif spec.given:
        placed_by = PlacedBy.GIVEN_REGION
    elif wanted.roi == ROI_FULL:
        placed_by = PlacedBy.WHOLE_IMAGE
    elif suggested_roi is not None and wanted.roi != ROI_AUTO:
        placed_by = PlacedBy.SOURCE
        spec = Region(outline=Rectangle(*(int(v) for v in suggested_roi)), exclude=spec.exclude)
        spec.check(shape)
    else:
        placed_by = PlacedBy.SPECIMEN
        specimen = find_specimen(image, subset)
        within, margin = specimen.mask.copy(), SPECIMEN_MARGIN
        # a subset within INTERPOLATION_MARGIN px of the image's edge is never ok (OUTSIDE_TARGET): none placed
        edge = INTERPOLATION_MARGIN
        within[:edge], within[-edge:], within[:, :edge], within[:, -edge:] = False, False, False, False
    region = spec.pixels(shape, within=within)
    return spec, region, placeable(region, subset, margin), placed_by, specimen


def region_middle(allowed: np.ndarray) -> tuple:
    """(x, y): the middle of a region that is no rectangle, where P0 is looked for.

    The row of the region's centroid, and on it the middle of the run of the region that holds the
    centroid (the centroid itself when it falls in a hole): across a dog-bone's gauge section, not the middle of its box, which shoulders cut off by
    the image's edge pull aside (the real dog-bone: x 404 for the box, 426 for the gauge section).
    """
    per_row, per_column = allowed.sum(axis=1), allowed.sum(axis=0)
    total = float(per_row.sum())
    cy = int(round(float(per_row @ np.arange(per_row.size)) / total))
    cx = float(per_column @ np.arange(per_column.size)) / total
    line = np.flatnonzero(allowed[cy])
    if line.size == 0:
        return cx, float(cy)
    breaks = np.flatnonzero(np.diff(line) > 1)
    starts, ends = np.r_[line[0], line[breaks + 1]], np.r_[line[breaks], line[-1]]
    inside = np.flatnonzero((starts <= cx) & (cx <= ends))
    if inside.size == 0:            # the centroid falls in a hole: P0 is looked for around it
        return cx, float(cy)
    return 0.5 * (starts[inside[0]] + ends[inside[0]]), float(cy)


def placeable_points(points: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Boolean (N,): the points (snapped to pixel centres, inside the image) whose subset ``allowed`` keeps."""
    snapped = np.floor(np.asarray(points, dtype=np.float64) + 0.5).astype(np.int64)
    height, width = allowed.shape
    inside = (snapped[:, 0] >= 0) & (snapped[:, 1] >= 0) & (snapped[:, 0] < width) & (snapped[:, 1] < height)
    keep = np.zeros(len(snapped), dtype=bool)
    keep[inside] = allowed[snapped[inside, 1], snapped[inside, 0]]
    return keep


def place_points(image: np.ndarray, wanted: PointsConfig, *, subset: int, suggested_roi: tuple | None = None) -> Placement:
    """The points on the reference ``image`` as ``wanted`` (a ``stream.session.config.PointsConfig``) asks.

    Where the points go, in order: the given points (``--points``; less those an exclusion or a mask
    leaves out); the given region (``--roi`` rectangle or polygon, ``--mask``); ``--roi full``; the
    source's region (``suggested_roi``: the simulator's gauge section, a recording's ROI); else, and with
    ``--roi auto``, the speckled specimen found in the image (``dic.region.find_specimen``, with
    ``SPECIMEN_MARGIN``). Exclusions apply to all. No subset reaches outside the region.

    Raises
    ------
    ValueError
        A region beyond the image or holding no whole subset, a mask of another size, given points or
        P0 outside the image (one line each).
    """
    height, width = image.shape[:2]
    spec, region, allowed, placed_by, specimen = where_points_go(image, wanted, subset=subset,
                                                                 suggested_roi=suggested_roi)
    given = wanted.xy

    dropped = 0
    step = None
    if given is not None:
        grid = np.asarray(given, dtype=np.float64).reshape(-1, 2)
        outside = (grid[:, 0] < 0) | (grid[:, 1] < 0) | (grid[:, 0] > width - 1) | (grid[:, 1] > height - 1)
        if outside.any():
            bad = grid[np.argmax(outside)]
            raise ValueError(f"{int(outside.sum())} of the given points lie outside the {width}x{height} image "
                             f"(first: {bad[0]:g},{bad[1]:g}): keep 0 <= x <= {width - 1} and 0 <= y <= {height - 1}")
        if spec.mask is not None or spec.exclude:
            keep = placeable_points(grid, allowed)
            dropped = int((~keep).sum())
            grid = grid[keep]
            if not len(grid):
                raise ValueError(f"every given point's subset reaches outside the region ({spec.describe()}): "
                                 f"none is left to track")
        region_for_p0 = allowed if (spec.mask is not None or spec.exclude) else None
    else:
        if not allowed.any():
            if placed_by is PlacedBy.SPECIMEN and not specimen.mask.any():
                raise ValueError("no speckled area in the first frame (a blank, unpainted or out-of-focus view?): "
                                 "point the camera at the speckled specimen, or say where the points go with "
                                 "--roi X,Y,W,H (--roi full: the whole image)")
            where = spec.describe() if placed_by is PlacedBy.GIVEN_REGION else placed_by.value
            raise ValueError(f"{where} holds no whole {subset}x{subset} subset: "
                             + ("give --roi, or a smaller --subset" if placed_by is PlacedBy.SPECIMEN else
                                "enlarge the region or use a smaller --subset"))
        step = wanted.step if wanted.step is not None else _step_for(allowed, wanted.n_points)
        grid = grid_in_region(allowed, step)
        region_for_p0 = allowed
    bounds = bounding_box(region) or (0, 0, width, height)
    shaped = placed_by is PlacedBy.SPECIMEN or (placed_by is PlacedBy.GIVEN_REGION and
                                                not isinstance(spec.outline, Rectangle))
    centre = region_middle(allowed) if shaped and allowed.any() else None
    p0_choice = choose_p0(image, bounds, subset, p0=wanted.p0, allowed=region_for_p0, centre=centre)
    p0 = np.floor(np.asarray(p0_choice.xy, dtype=np.float64) + 0.5)
    if not (0 <= p0[0] < width and 0 <= p0[1] < height):
        raise ValueError(f"P0 ({p0[0]:g}, {p0[1]:g}) is outside the {width}x{height} image")
    same = np.all(np.floor(grid + 0.5) == p0[None, :], axis=1)
    points = np.vstack([p0[None, :], grid[~same]])
    return Placement(points=points, p0=p0_choice, step=step, bounds=bounds, region=region, placed_by=placed_by,
                     specimen=specimen, spec=spec, dropped=dropped)


def build_points(shape: tuple[int, int], *, roi: Sequence[int] | None, step: int | None, n_points: int, subset: int,
                 p0: Sequence[float] | None = None,
                 points: np.ndarray | None = None) -> tuple[np.ndarray, tuple[int, ...], int | None]:
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
    first = np.floor(np.asarray(p0, dtype=np.float64) + 0.5)
    if not (0 <= first[0] < width and 0 <= first[1] < height):
        raise ValueError(f"P0 ({first[0]:g}, {first[1]:g}) is outside the {width}x{height} image")
    same = np.all(np.floor(grid + 0.5) == first[None, :], axis=1)
    grid = grid[~same]
    return np.vstack([first[None, :], grid]), tuple(int(v) for v in roi), step


# Tracker memory per point, measured with IC-GN and the seeded search on 1 MP: 5,184 points 31 MB,
# 40,401 points 280 MB (reference subset, gradients, Hessian and per-point state): ~7 KB.
TRACKER_BYTES_PER_POINT = 7_000
# One point's share of a recorded result set: x, y, u, v, zncc, ux, uy, vx, vy (float64), point id,
# status, iterations and ok.
RESULT_BYTES_PER_POINT = 90


def _size(n_bytes: float) -> str:
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def check_point_count(n_points: int, max_points: int, *, how: str, frames: int | None = None,
                      recording: bool = True) -> None:
    """ValueError (one line, with the cost) when ``n_points`` is more than ``max_points``."""
    if n_points <= max_points:
        return
    cost = f"about {_size(n_points * TRACKER_BYTES_PER_POINT)} of memory"
    if frames and recording:
        cost += f" and {_size(n_points * RESULT_BYTES_PER_POINT * frames)} of results recorded over {frames} frames"
    raise ValueError(f"{how} gives {n_points:,} points, more than livedic run tracks live (--max-points "
                     f"{max_points:,}; {cost}, and frames are dropped when tracking takes longer than a frame "
                     f"period): use a larger --step, fewer --n-points or a smaller --roi, or raise --max-points")
