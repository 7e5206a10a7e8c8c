"""Tests of dic/stereo/frame.py's helpers: the right view's tracking points and their sub-pixel offsets, the
specimen's best-fit frame, the 3D extensometer."""

import numpy as np
import pytest

from livedic.dic.stereo import StereoMatch, StereoStatus, extensometer_3d, follow, right_track_points, specimen_frame
from livedic.dic.stereo.triangulate import Triangulation


def a_match(right, status):
    n = len(right)
    nan = np.full(n, np.nan)
    return StereoMatch(left=np.zeros((n, 2)), right=np.asarray(right, dtype=float), gradients=np.zeros((n, 4)),
                       zncc=np.ones(n), triangulation=Triangulation(np.zeros((n, 3)), nan, nan, nan,
                                                                    np.asarray(status, dtype=np.int8)),
                       status=np.asarray(status, dtype=np.int8), match_status=np.zeros(n, dtype=np.int8))


def test_the_right_view_tracks_snapped_centres_and_follows_the_offset_with_the_warp():
    match = a_match([[10.3, 20.6], [5.5, 7.49], [np.nan, np.nan]], [0, 0, StereoStatus.NOT_MATCHED])
    centres, offsets = right_track_points(match)
    np.testing.assert_array_equal(centres[:2], [[10.0, 21.0], [6.0, 7.0]])       # halves round up
    np.testing.assert_allclose(offsets[:2], [[0.3, -0.4], [-0.5, 0.49]], atol=1e-12)
    assert np.all(np.isnan(centres[2])) and np.all(offsets[2] == 0.0)
    # the subset moved by (1, 2) and stretched 2 % along x: the offset point moves with the material
    now = follow(centres[:2] + [1.0, 2.0], offsets[:2], ux=[0.02, 0.02], uy=[0.0, 0.0], vx=[0.0, 0.0], vy=[0.0, 0.0])
    np.testing.assert_allclose(now, match.right[:2] + [1.0, 2.0] + offsets[:2] * [0.02, 0.0], atol=1e-12)
    np.testing.assert_allclose(follow(centres[:2], offsets[:2]), match.right[:2], atol=1e-12)


def test_the_specimen_frame_puts_w_along_the_plane_normal_away_from_the_cameras():
    rng = np.random.default_rng(0)
    tilt = np.radians(30.0)
    e1, e3 = np.array([np.cos(tilt), 0.0, np.sin(tilt)]), np.array([-np.sin(tilt), 0.0, np.cos(tilt)])
    points = 300.0 * e3 + rng.uniform(-20, 20, (50, 1)) * e1 + rng.uniform(-20, 20, (50, 1)) * [0.0, 1.0, 0.0]
    frame = specimen_frame(points)
    np.testing.assert_allclose(frame.rotation, np.stack([e1, [0.0, 1.0, 0.0], e3]), atol=1e-12)
    np.testing.assert_allclose(frame.to_specimen(points)[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(frame.turn([e3 * 0.5]), [[0.0, 0.0, 0.5]], atol=1e-12)
    with pytest.raises(ValueError, match="on a line"):
        specimen_frame(np.outer(np.arange(5.0), [1.0, 0.0, 0.0]) + [0.0, 0.0, 300.0])
    with pytest.raises(ValueError, match="at least 3"):
        specimen_frame(np.full((4, 3), np.nan))


def test_the_3d_extensometer_is_nan_when_an_end_is_lost():
    reference = np.array([[0.0, 0.0, 300.0], [30.0, 0.0, 310.0], [0.0, 5.0, 300.0]])
    current = reference * [1.0, 1.0, 1.0] + [[0.0, 0.0, 1.0], [0.3, 0.0, 1.1], [np.nan, np.nan, np.nan]]
    reading = extensometer_3d(reference, current, [[0, 1], [0, 2]])
    assert reading.length0_mm[0] == pytest.approx(np.hypot(30.0, 10.0))
    assert reading.length_mm[0] == pytest.approx(np.hypot(30.3, 10.1))
    assert reading.strain[0] == pytest.approx(np.hypot(30.3, 10.1) / np.hypot(30.0, 10.0) - 1.0)
    assert np.isnan(reading.strain[1]) and np.isnan(reading.length_mm[1])
