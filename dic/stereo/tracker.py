"""``StereoTracker``: both views of each new pair tracked from their reference images, then triangulated.

The reference pair is matched once (``dic.stereo.match``); the left view's tracker follows every left point, the
right view's tracker follows the matched points only (their subset centres: ``right_track_points``), and
``follow`` carries each match's sub-pixel offset along with the right subset's warp. Each ``track`` returns a
``StereoMeasurement``: the left view's 2D measurement as every 2D consumer reads it (its ``u, v``, status ...),
plus the right view's positions and the 3D points (``StereoPoints``). A point is ok in 3D only where the match,
both views' tracking and the triangulation are (``dic.stereo.frame``).

The trackers are built by the caller (``make_tracker(reference_image, points)``: the live session's
``TrackingConfig.tracker``, key frames and all), so this module stays free of the session's options. Pure
computation: no I/O, no threads.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from livedic.dic.calibration import StereoCalibration
from livedic.dic.result import Measurement
from livedic.dic.stereo.frame import StereoPoints, follow, right_track_points, stereo_points
from livedic.dic.stereo.match import StereoMatch
from livedic.dic.stereo.triangulate import DEFAULT_MAX_EPIPOLAR_PX

MakeTracker = Callable[[np.ndarray, np.ndarray], Any]


@dataclass
class StereoMeasurement(Measurement):
    """One pair's measurement: the left view's 2D ``Measurement`` fields, and

    right_xy : float64 (N, 2)   where each point's material is in the right image (NaN where not tracked there)
    right_ok : bool (N,)        the right view's tracking status per point (False where unmatched)
    points : StereoPoints       X, Y, Z, U, V, W (mm, left camera frame) and the 3D status per point
    """

    right_xy: np.ndarray | None = None
    right_ok: np.ndarray | None = None
    points: StereoPoints | None = None


class StereoTracker:
    """Track both views of a stereo pair and triangulate (module notes).

    Parameters
    ----------
    calibration : StereoCalibration
    match : StereoMatch
        The reference pair's left -> right match (``dic.stereo.match_stereo`` on the reference images).
    left_reference, right_reference : ndarray, shape (H, W)
        The reference pair.
    make_tracker : callable
        ``make_tracker(reference_image, points (M, 2)) -> tracker`` with ``track(image) -> Measurement`` (a
        ``dic.tracking.KeyFrameTracker`` in a session).
    max_epipolar_px : float
        Bound of each frame's triangulation (``dic.stereo.triangulate``).
    """

    def __init__(self, calibration: StereoCalibration, match: StereoMatch, left_reference: np.ndarray,
                 right_reference: np.ndarray, make_tracker: MakeTracker, *,
                 max_epipolar_px: float = DEFAULT_MAX_EPIPOLAR_PX) -> None:
        if not np.any(match.ok):
            raise ValueError("no point of the left view was matched in the right view: check the calibration "
                             "(is it this rig's?), the depth range and that both cameras see the speckle")
        self.calibration = calibration
        self.match = match
        self.max_epipolar_px = float(max_epipolar_px)
        self.matched = np.flatnonzero(match.ok)
        centres, self._offsets = right_track_points(match)
        self.left = make_tracker(left_reference, match.left)
        self.right = make_tracker(right_reference, centres[self.matched])
        self.frames_tracked = 0
        self.last_points: StereoPoints | None = None

    @property
    def n_points(self) -> int:
        return len(self.match.status)

    # what a session reads of its tracker after each frame: the left view's 2D fields, both views' work together
    @property
    def trackable(self) -> np.ndarray:
        """The left view's trackable points (N,): the 2D fields a StereoMeasurement carries are the left view's."""
        return self.left.trackable

    @property
    def last_trackable(self) -> np.ndarray:
        """The left view's points the frame just tracked tried (``KeyFrameTracker.last_trackable``: never waits for
        a new key frame's tracker being built)."""
        left = getattr(self.left, "last_trackable", None)
        return left if left is not None else self.left.trackable

    def build_on(self, executor: Any) -> None:
        """Both views build their new key frames' trackers on ``executor`` (``KeyFrameTracker.build_on``)."""
        for view in (self.left, self.right):
            build_on = getattr(view, "build_on", None)
            if build_on is not None:
                build_on(executor)

    @property
    def last_refind_attempts(self) -> int:
        return int(getattr(self.left, "last_refind_attempts", 0)) + int(getattr(self.right, "last_refind_attempts", 0))

    @property
    def last_refound(self) -> np.ndarray:
        """Points re-found by a search in either view this frame (N,)."""
        refound = np.zeros(self.n_points, dtype=bool)
        left = getattr(self.left, "last_refound", None)
        right = getattr(self.right, "last_refound", None)
        if left is not None:
            refound |= np.asarray(left, dtype=bool)
        if right is not None:
            refound[self.matched] |= np.asarray(right, dtype=bool)
        return refound

    @property
    def last_update(self) -> Any:
        """A move of the left view's reference this frame, else the right's, else None."""
        left = getattr(self.left, "last_update", None)
        return left if left is not None else getattr(self.right, "last_update", None)

    @property
    def last_fracture(self) -> Any:
        return getattr(self.left, "last_fracture", None)

    @property
    def last_timings(self) -> dict[str, int] | None:
        """Both views' stage times (ns) summed: the pair's cost per stage."""
        left, right = getattr(self.left, "last_timings", None), getattr(self.right, "last_timings", None)
        if left is None or right is None:
            return None
        return {name: left.get(name, 0) + right.get(name, 0) for name in {*left, *right}}

    def track(self, left_image: np.ndarray, right_image: np.ndarray) -> StereoMeasurement:
        """Both views tracked from their references and triangulated: a ``StereoMeasurement``."""
        left = self.left.track(left_image)
        right = self.right.track(right_image)
        n = self.n_points
        right_xy = np.full((n, 2), np.nan)
        right_ok = np.zeros(n, dtype=bool)
        centres_now = np.column_stack([right.x + right.u, right.y + right.v])
        gradients = [getattr(right, name) for name in ("ux", "uy", "vx", "vy")]
        right_xy[self.matched] = follow(centres_now, self._offsets[self.matched], *gradients)
        right_ok[self.matched] = right.ok
        left_xy = np.column_stack([left.x + left.u, left.y + left.v])
        points = stereo_points(self.calibration, self.match, left_xy, left.ok, right_xy, right_ok,
                               max_epipolar_px=self.max_epipolar_px)
        self.frames_tracked += 1
        self.last_points = points
        fields = {name: getattr(left, name) for name in Measurement.__dataclass_fields__}
        return StereoMeasurement(**fields, right_xy=right_xy, right_ok=right_ok, points=points)
