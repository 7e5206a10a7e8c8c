"""Virtual extensometers in space: each end's 3D position fitted from the band of points around it, the length
between the two ends measured in 3D (mm), free of out-of-plane motion and of the specimen's tilt.

The ends and their bands are the 2D extensometers' (``dic.strain.extensometer.place_extensometers`` on the left
view's reference points): the same fit that gives a 2D end's displacement gives here its position X, Y, Z (a
position is fitted like a displacement: both are smooth fields over the band), in the reference pair and in the
current one; the regions of a crack are kept apart the same way. Pure functions on arrays.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from livedic.dic.strain.extensometer import ExtensometerReadings, ExtensometerSet, ExtensometerStatus, end_displacements


def end_positions_3d(placed: ExtensometerSet, points_px: npt.ArrayLike, xyz: npt.ArrayLike, ok: npt.ArrayLike, *,
                     point_labels: np.ndarray | None = None, end_labels: np.ndarray | None = None) -> np.ndarray:
    """(2E, 3) positions (mm) of every end, fitted over its band of points (NaN where the end is lost).

    ``points_px`` (N, 2): the reference positions the extensometers were placed on (left view px); ``xyz`` (N, 3):
    the points' 3D positions in one frame; ``ok`` (N,): which of them are measured.
    """
    points = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
    measured = np.asarray(ok, dtype=bool) & np.all(np.isfinite(xyz), axis=1)
    filled = np.where(measured[:, None], xyz, 0.0)
    ex, ey = end_displacements(placed, points, filled[:, 0], filled[:, 1], measured, point_labels=point_labels,
                               end_labels=end_labels)
    ez, _ = end_displacements(placed, points, filled[:, 2], filled[:, 2], measured, point_labels=point_labels,
                              end_labels=end_labels)
    return np.column_stack([ex, ey, ez])


def read_extensometers_3d(placed: ExtensometerSet, points_px: npt.ArrayLike, reference_xyz: npt.ArrayLike,
                          reference_ok: npt.ArrayLike, xyz: npt.ArrayLike, ok: npt.ArrayLike, *,
                          point_labels: np.ndarray | None = None,
                          end_labels: np.ndarray | None = None) -> ExtensometerReadings:
    """Every extensometer's reading in one stereo frame: lengths in mm between ends fitted in 3D.

    Parameters
    ----------
    placed : ExtensometerSet
        Placed on ``points_px`` (the left view's reference points).
    points_px : array (N, 2)
    reference_xyz, reference_ok : arrays (N, 3), (N,)
        The points in the reference pair (mm) and which are measured there.
    xyz, ok : arrays (N, 3), (N,)
        The points in this frame.
    point_labels, end_labels : arrays, optional
        Regions not to mix (the sides of a crack), as ``dic.strain.extensometer.end_displacements``.

    Returns
    -------
    ExtensometerReadings
        ``l0_mm``, ``length_mm`` set; ``l0_px``, ``length_px`` NaN; END_LOST where an end cannot be fitted in
        either frame.
    """
    first, second = slice(0, None, 2), slice(1, None, 2)
    ends0 = end_positions_3d(placed, points_px, reference_xyz, reference_ok)
    ends = end_positions_3d(placed, points_px, xyz, ok, point_labels=point_labels, end_labels=end_labels)
    l0 = np.linalg.norm(ends0[second] - ends0[first], axis=1)
    length = np.linalg.norm(ends[second] - ends[first], axis=1)
    lost = ~np.isfinite(length) | ~np.isfinite(l0)
    status = np.where(lost, int(ExtensometerStatus.END_LOST), int(ExtensometerStatus.OK)).astype(np.int32)
    length = np.where(lost, np.nan, length)
    with np.errstate(invalid="ignore", divide="ignore"):
        eng = length / l0 - 1.0
        true = np.log(length / l0)
    nan = np.full(len(placed.names), np.nan)
    return ExtensometerReadings(names=placed.names, l0_px=nan, length_px=nan.copy(), eng_strain=eng, true_strain=true,
                                status=status, l0_mm=l0, length_mm=length)
