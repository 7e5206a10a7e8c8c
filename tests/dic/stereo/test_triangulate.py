"""Tests of dic/stereo/triangulate.py: exact projections triangulate exactly; what cannot be trusted is flagged."""

import numpy as np
import pytest

from livedic.dic.stereo import StereoStatus, project, triangulate
from tests.dic.stereo.rig import rig


@pytest.fixture(scope="module")
def calibration():
    return rig().calibration()


def random_points(n=300, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-25, 25, n), rng.uniform(-18, 18, n), rng.uniform(270, 330, n)])


def test_exact_projections_through_distorting_lenses_triangulate_to_the_points(calibration):
    points = random_points()
    left, right = project(calibration, points)
    result = triangulate(calibration, left, right)
    assert np.all(result.ok)
    np.testing.assert_allclose(result.xyz, points, atol=1e-6, rtol=0)
    # exact projections lie on each other's epipolar lines and reproject onto themselves
    assert np.max(result.epipolar_px) < 1e-6
    assert np.max(result.reprojection_left_px) < 1e-6 and np.max(result.reprojection_right_px) < 1e-6


def test_image_noise_splits_between_the_views_as_the_reprojection_errors(calibration):
    """Moving the right position along y by 0.1 px: an epipolar distance of about 0.1 px (the epipolar lines
    of a rig turned about y run along x), split between the views, the point moved by a fraction of a mm."""
    points = random_points(50, seed=1)
    left, right = project(calibration, points)
    result = triangulate(calibration, left, right + [0.0, 0.1])
    assert np.all(result.ok)
    np.testing.assert_allclose(result.epipolar_px, 0.1, atol=0.01)
    np.testing.assert_allclose(result.reprojection_left_px + result.reprojection_right_px, result.epipolar_px,
                               rtol=0.05)
    assert np.max(np.linalg.norm(result.xyz - points, axis=1)) < 0.05


def test_untrustworthy_points_are_nan_with_their_reason(calibration):
    points = random_points(6, seed=2)
    left, right = project(calibration, points)
    left[0] = np.nan                                  # not tracked in the left view
    right[1] = [np.inf, 3.0]
    right[2, 1] += 2.0                                # 2 px off the epipolar line: a wrong match
    behind_left, behind_right = project(calibration, -points[3:4])   # rays meeting behind the cameras
    left[3], right[3] = behind_left[0], behind_right[0]
    result = triangulate(calibration, left, right)
    expected = [StereoStatus.NOT_FINITE, StereoStatus.NOT_FINITE, StereoStatus.EPIPOLAR, StereoStatus.BEHIND_CAMERA,
                StereoStatus.OK, StereoStatus.OK]
    assert result.status.tolist() == expected
    assert np.all(np.isnan(result.xyz[:4])) and np.all(np.isfinite(result.xyz[4:]))
    assert result.epipolar_px[2] == pytest.approx(2.0, abs=0.1)      # the value judged is kept
    # a looser bound accepts the off-line pair (the caller's choice)
    assert triangulate(calibration, left, right, max_epipolar_px=3.0).status[2] == StereoStatus.OK


def test_mismatched_inputs_are_refused(calibration):
    with pytest.raises(ValueError, match="one pair per point"):
        triangulate(calibration, np.zeros((3, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="max_epipolar_px"):
        triangulate(calibration, np.zeros((1, 2)), np.zeros((1, 2)), max_epipolar_px=0.0)


def test_the_vectorised_correction_is_opencvs_optimal_one():
    """Lindstrom's two steps land where cv2.correctMatches (the exact sextic) does, to 1e-9 px, on the sub-pixel
    epipolar errors DIC positions have; the corrected pairs satisfy the epipolar constraint to rounding."""
    import cv2

    from livedic.dic.stereo.triangulate import correct_matches
    from tests.dic.stereo.rig import rig

    calibration = rig().calibration()
    F = calibration.fundamental_matrix()
    rng = np.random.default_rng(4)
    world = np.column_stack([rng.uniform(-20, 20, 400), rng.uniform(-15, 15, 400), rng.uniform(290, 310, 400)])
    P_left, P_right = calibration.projection_matrices()
    homogeneous = np.column_stack([world, np.ones(len(world))])
    left = (P_left @ homogeneous.T).T
    right = (P_right @ homogeneous.T).T
    left = left[:, :2] / left[:, 2:] + rng.normal(0.0, 0.05, (400, 2))
    right = right[:, :2] / right[:, 2:] + rng.normal(0.0, 0.05, (400, 2))
    want_left, want_right = cv2.correctMatches(F, left.reshape(1, -1, 2), right.reshape(1, -1, 2))
    got_left, got_right = correct_matches(F, left, right)
    np.testing.assert_allclose(got_left, want_left.reshape(-1, 2), atol=1e-9)
    np.testing.assert_allclose(got_right, want_right.reshape(-1, 2), atol=1e-9)
    residual = np.einsum("ni,ij,nj->n", np.column_stack([got_right, np.ones(400)]), F,
                         np.column_stack([got_left, np.ones(400)]))
    assert np.abs(residual).max() < 1e-9
