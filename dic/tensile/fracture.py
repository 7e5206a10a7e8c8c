"""Fracture: a band of points lost at once, with the material on either side jumping apart.

When a specimen breaks, the points whose subsets straddle the crack are lost in the same
frame, along a line, and the two halves move apart: the displacement of the points on one
side of that line jumps relative to the other side's. Neither alone is a fracture: points
are lost together when something passes in front of the camera (no jump), and a grip slip
moves everything (no band). ``detect_fracture`` asks for both:

1. **A band**: at least ``MIN_LOST_POINTS`` points (and ``MIN_LOST_SHARE`` of those tracked)
   that were ok in the previous frame are not ok now, and they lie along a line: the
   spread of their positions across their principal direction is at most ``MAX_BAND_WIDTH``
   grid steps, and along it they span at least ``MIN_BAND_LENGTH`` of the tracked points'
   extent that way.
2. **A jump**: the ok points on the two sides of that line moved apart since the previous
   frame: the difference of the median displacement increments of the two sides is at
   least ``MIN_JUMP_PX``.
3. **An opening**: that jump opens the line, it does not slide along it: its component
   across the line is at least ``MIN_OPENING_SHARE`` of it. A crack opens (a tensile crack
   straight across, a shear crack at 45 degrees still opens by cos 45); the edge of a
   specimen moving past a static background, a grip or a ruler is a band of lost points
   with a jump along the band (seen on a real dog-bone with the whole image as ROI: two
   "fractures" along its straight edges, both within 6 degrees of the load axis).

A detected fracture names the points to stop tracking (``Fracture.separated``): every point
within a subset's width of the crack line, lost or not (a subset across a crack measures
neither side), so wide searches are no longer spent on them; the rest go on.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

MIN_LOST_POINTS = 8
MIN_LOST_SHARE = 0.005
MAX_BAND_WIDTH = 2.0          # grid steps, across the band
MIN_BAND_LENGTH = 0.5         # share of the points' extent along the band
MIN_JUMP_PX = 1.0
MIN_OPENING_SHARE = 0.5       # cos 60 deg: the jump's share across the band


@dataclass(frozen=True)
class Fracture:
    """A detected fracture.

    Attributes
    ----------
    centre : (x, y)
        A point of the crack line (reference px).
    direction : (dx, dy)
        Unit vector along the crack.
    lost : int
        Points lost in the frame it was detected.
    jump_px : float
        How far the two sides moved apart in that frame.
    separated : ndarray of bool (N,)
        The points to stop tracking (within a subset's width of the crack line).
    side : ndarray of int8 (N,)
        -1 or +1: which side of the crack line each point lies on (0 on the line).
    """
    centre: tuple
    direction: tuple
    lost: int
    jump_px: float
    separated: np.ndarray
    side: np.ndarray

    def describe(self) -> str:
        angle = float(np.degrees(np.arctan2(self.direction[1], self.direction[0]))) % 180.0
        return (f"fracture: {self.lost} points lost at once along a line through ({self.centre[0]:.0f}, "
                f"{self.centre[1]:.0f}) px at {angle:.0f} deg, the two sides {self.jump_px:.1f} px apart in one "
                f"frame; {int(self.separated.sum())} points across the crack no longer tracked")


def detect_fracture(x: npt.ArrayLike, y: npt.ArrayLike, ok_before: npt.ArrayLike, ok_now: npt.ArrayLike,
                    u_before: np.ndarray, v_before: np.ndarray, u_now: np.ndarray, v_now: np.ndarray, *,
                    step: float, subset: int, trackable: npt.ArrayLike | None = None) -> Fracture | None:
    """A ``Fracture`` when the points newly lost form a band across which the material jumped, else None.

    Parameters
    ----------
    x, y : arrays (N,)
        Reference positions of the points, px.
    ok_before, ok_now : arrays (N,) of bool
        Which points were ok in the previous frame and are ok now.
    u_before, v_before, u_now, v_now : arrays (N,)
        Their displacements then and now (NaN where not ok).
    step : float
        Grid step, px.
    subset : int
        Subset side, px: the points within a subset's width of the crack are separated.
    trackable : arrays (N,) of bool, optional
        Points being tracked (default all).
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    trackable = np.ones(x.size, dtype=bool) if trackable is None else np.asarray(trackable, dtype=bool)
    lost = np.asarray(ok_before, dtype=bool) & ~np.asarray(ok_now, dtype=bool) & trackable
    n_lost = int(lost.sum())
    if n_lost < max(MIN_LOST_POINTS, MIN_LOST_SHARE * int(trackable.sum())):
        return None
    where = np.column_stack([x[lost], y[lost]])
    centre = where.mean(axis=0)
    values, vectors = np.linalg.eigh(np.cov((where - centre).T))
    along, across = vectors[:, 1], vectors[:, 0]
    width = float(np.sqrt(max(values[0], 0.0)))
    all_points = np.column_stack([x[trackable], y[trackable]])
    extent = np.ptp(all_points @ along) if len(all_points) > 1 else 0.0
    length = np.ptp(where @ along)
    if width > MAX_BAND_WIDTH * step or length < MIN_BAND_LENGTH * extent:
        return None
    offset = (np.column_stack([x, y]) - centre) @ across
    side = np.sign(np.where(np.abs(offset) < 1e-9, 0.0, offset)).astype(np.int8)
    both = np.asarray(ok_before, dtype=bool) & np.asarray(ok_now, dtype=bool)
    du = np.asarray(u_now) - np.asarray(u_before)
    dv = np.asarray(v_now) - np.asarray(v_before)
    increments = []
    for s in (-1, 1):
        chosen = both & (side == s) & np.isfinite(du) & np.isfinite(dv)
        if chosen.sum() < MIN_LOST_POINTS:
            return None
        increments.append((np.median(du[chosen]), np.median(dv[chosen])))
    relative = np.subtract(increments[1], increments[0])
    jump = float(np.hypot(*relative))
    if jump < MIN_JUMP_PX:
        return None
    if abs(float(relative @ across)) < MIN_OPENING_SHARE * jump:
        return None             # sliding along the band: an edge passing a static background, not a crack
    # every point there, tracked now or not: one not tracked in this key frame (too little texture left)
    # could be taken up again by a later reference, across the crack
    separated = np.abs(offset) <= max(float(subset), width + 0.5 * subset)
    return Fracture(centre=(float(centre[0]), float(centre[1])), direction=(float(along[0]), float(along[1])),
                    lost=n_lost, jump_px=jump, separated=separated, side=side)
