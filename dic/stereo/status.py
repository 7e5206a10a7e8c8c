"""Why a stereo point has no 3D position: ``StereoStatus`` (status as data, one code per point).

A point is OK only when both views hold it, the two image positions agree with the calibration's epipolar
geometry and the ray intersection lies in front of both cameras; anything else is NaN with one of these codes.
"""

from __future__ import annotations

import enum


class StereoStatus(enum.IntEnum):
    """Why a point has no 3D position (0: it has one)."""

    OK = 0
    NOT_FINITE = 1          # an image position is NaN or infinite (not tracked or not matched in a view)
    LEFT_NOT_OK = 2         # the left view's tracker flagged the point
    RIGHT_NOT_OK = 3        # the right view's tracker flagged the point
    NOT_MATCHED = 4         # the left -> right match on the reference pair failed (see its dic Status)
    LOW_CORRELATION = 5     # the left -> right match's ZNCC is below the acceptance threshold
    EPIPOLAR = 6            # the two image positions are further from each other's epipolar line than the bound
    BEHIND_CAMERA = 7       # the rays meet behind (or at) one of the cameras: a wrong match
    OUTLIER = 8             # the left -> right match disagrees with its neighbours' (normalised median test)

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    StereoStatus.OK: "measured in 3D",
    StereoStatus.NOT_FINITE: "an image position is not finite (not tracked or not matched in one view)",
    StereoStatus.LEFT_NOT_OK: "the left view's tracking flagged the point",
    StereoStatus.RIGHT_NOT_OK: "the right view's tracking flagged the point",
    StereoStatus.NOT_MATCHED: "the left-to-right match on the reference pair failed",
    StereoStatus.LOW_CORRELATION: "the left-to-right match's ZNCC is below the acceptance threshold",
    StereoStatus.EPIPOLAR: "the two views' positions are off each other's epipolar line by more than the bound",
    StereoStatus.BEHIND_CAMERA: "the two rays meet behind a camera",
    StereoStatus.OUTLIER: "the left-to-right match disagrees with its neighbours' matches",
}
