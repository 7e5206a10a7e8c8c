"""Tests of dic/calibration/solve.py: Zhang's solution against the simulator's known lens, the specimen
plane's scale, the refusals."""

import numpy as np
import pytest

from livedic.dic.calibration import (CalibrationRefused, Detection, calibrate, detect_target, plane_scale,
                                     undistort_points)


def test_calibration_recovers_the_simulated_lens(chessboard_views):
    spec, square, lens, views, _ = chessboard_views
    found = [(name, detect_target(image, spec, square)) for name, image in views]
    assert all(isinstance(d, Detection) and d.image_points.shape == (54, 2) for _, d in found)
    calibration = calibrate(found, lens.size, target=spec.text, square_mm=square)
    assert calibration.rms_px < 0.15 and all(fit.rms_px < 0.2 for fit in calibration.images)
    K, true_K = calibration.camera_matrix, lens.camera_matrix
    # Tolerances for these 9 views (1 grey level of noise); measured: f within 0.05 %, principal point
    # within 1.4 px, k1 -0.1220 for -0.12.
    np.testing.assert_allclose(np.diag(K)[:2], np.diag(true_K)[:2], rtol=0.01)
    np.testing.assert_allclose(K[:2, 2], true_K[:2, 2], atol=2.0)
    assert abs(calibration.dist_coeffs[0] - lens.k1) < 0.01
    # What matters to a measurement: the undistortion the calibration gives matches the lens's
    # within 0.5 px over the central 80 % of the image (where the views put the board; beyond it the model extrapolates).
    grid = np.stack(np.meshgrid(np.linspace(51, 460, 9), np.linspace(51, 460, 9)), axis=-1).reshape(-1, 2)
    ideal_true = lens.undistort(grid)
    ideal = undistort_points(calibration, grid)
    # The two cameras differ by their K: compare after removing the best similarity (scale + shift).
    A = np.column_stack([ideal, np.ones(len(ideal))])
    fit, *_ = np.linalg.lstsq(A, ideal_true, rcond=None)
    assert np.max(np.abs(A @ fit - ideal_true)) < 0.5       # measured 0.40 px (k2, p1 and the principal point trade)


def test_plane_scale_is_the_rendered_px_per_mm(chessboard_views):
    spec, square, lens, views, plane = chessboard_views
    calibration = calibrate([(n, detect_target(i, spec, square)) for n, i in views], lens.size, target=spec.text,
                            square_mm=square)
    scale = plane_scale(calibration, "plane.png", detect_target(plane, spec, square))
    # rendered at 2.0 ideal px/mm of the TRUE camera; the calibrated camera's focal length differs by its error
    expected = 2.0 * calibration.camera_matrix[0, 0] / lens.camera_matrix[0, 0]
    assert abs(scale.px_per_mm - expected) / expected < 0.003
    assert scale.tilt_deg < 1.0 and scale.rms_px < 0.2


def test_too_few_views_and_a_bad_fit_are_refused(chessboard_views):
    spec, square, lens, views, _ = chessboard_views
    found = [(n, detect_target(i, spec, square)) for n, i in views]
    with pytest.raises(CalibrationRefused, match="at least 3"):
        calibrate(found[:2], lens.size, target=spec.text, square_mm=square)
    # one view's corners displaced by a board that moved: refused, naming that view
    name, detection = found[2]
    moved = Detection(detection.image_points + np.random.default_rng(1).normal(0, 1.5, detection.image_points.shape),
                      detection.ids, detection.object_points)
    with pytest.raises(CalibrationRefused, match=name) as error:
        calibrate(found[:2] + [(name, moved)] + found[3:], lens.size, target=spec.text, square_mm=square)
    assert "--max-error" in str(error.value) and "\n" not in str(error.value)
