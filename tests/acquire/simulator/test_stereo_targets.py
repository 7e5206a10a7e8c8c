"""Tests of acquire/simulator/targets.py's stereo pairs: views around a rig's aim point seen whole by both cameras,
rendered where the rig puts the corners in each view, and boards too large or rigs without an aim point refused."""

import cv2
import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.targets import (STEREO_VIEWS, board_in_view, render_target_pair, rig_aim_mm,
                                               stereo_calibration_views, stereo_square_mm)
from livedic.dic.calibration import Detection, detect_target, parse_target


@pytest.fixture(scope="module")
def rig():
    return StereoRig.symmetric(Lens((480, 360), k1=-0.1, p1=0.0003), Lens((480, 360), k1=-0.06, focal_px=500.0),
                               distance_mm=250.0, angle_deg=30.0)


def test_the_views_surround_the_aim_point_tilted_and_whole_in_both_cameras(rig):
    np.testing.assert_allclose(rig_aim_mm(rig), [0.0, 0.0, 250.0], atol=1e-9)
    spec = parse_target("chessboard:9x6")
    square = stereo_square_mm(spec, rig)
    poses = stereo_calibration_views(spec, square, rig)
    assert len(poses) == len(STEREO_VIEWS)
    normals = []
    for pose in poses:
        assert board_in_view(spec, square, rig.left, pose) and board_in_view(spec, square, rig.right,
                                                                             rig.right_pose(pose))
        normals.append(cv2.Rodrigues(pose.rvec)[0][:, 2])
    # tilted in several directions (Zhang needs them): the normals spread over more than 20 degrees
    spread = max(np.degrees(np.arccos(np.clip(a @ b, -1, 1))) for a in normals for b in normals)
    assert spread > 20.0


def test_a_pair_shows_the_corners_where_the_rig_puts_them_in_each_view(rig):
    spec = parse_target("chessboard:9x6")
    square = stereo_square_mm(spec, rig)
    pose = stereo_calibration_views(spec, square, rig)[1]
    for image, lens, seen in zip(render_target_pair(spec, square, rig, pose, noise=0.5, seed=1),
                                 (rig.left, rig.right), (pose, rig.right_pose(pose))):
        found = detect_target(image, spec, square)
        assert isinstance(found, Detection)
        truth, _ = cv2.projectPoints(spec.object_points(square), seen.rvec, seen.tvec, lens.camera_matrix,
                                     lens.dist_coeffs)
        truth = truth.reshape(-1, 2)
        # OpenCV may number a chessboard from either end
        error = min((np.hypot(*(found.image_points - order).T) for order in (truth, truth[::-1])), key=np.max)
        assert np.sqrt(np.mean(error ** 2)) < 0.15 and error.max() < 0.5


def test_a_board_too_large_or_a_rig_without_an_aim_point_is_refused(rig):
    spec = parse_target("chessboard:9x6")
    with pytest.raises(ValueError, match="use smaller squares"):
        stereo_calibration_views(spec, 3.0 * stereo_square_mm(spec, rig), rig)
    parallel = StereoRig(rig.left, rig.right, np.eye(3), np.array([-100.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="parallel"):
        rig_aim_mm(parallel)


def test_a_long_lens_gets_steeper_views_of_a_board_half_its_field_wide():
    from livedic.acquire.simulator.targets import (NARROW_STEREO_VIEW_FILL, NARROW_STEREO_VIEWS, STEREO_VIEW_FILL,
                                                   board_extent, stereo_view_plan)

    # a 50 mm lens on a 1 MP camera at 300 mm: f 8000 px on 1024 px, a 7.3 degree field, ~38 mm wide at the aim
    lens = Lens((1024, 768), k1=-0.05, focal_px=8000.0)
    narrow = StereoRig.symmetric(lens, lens, distance_mm=300.0, angle_deg=25.0)
    views, fill = stereo_view_plan(narrow)
    assert (views, fill) == (NARROW_STEREO_VIEWS, NARROW_STEREO_VIEW_FILL)
    wide = StereoRig.symmetric(Lens((1024, 768), focal_px=4000.0), Lens((1024, 768), focal_px=4000.0),
                               distance_mm=300.0, angle_deg=25.0)
    assert stereo_view_plan(wide) == (STEREO_VIEWS, STEREO_VIEW_FILL)
    spec = parse_target("chessboard:9x6")
    square = stereo_square_mm(spec, narrow, fill)
    x0, _, x1, _ = board_extent(spec, square)
    assert x1 - x0 == pytest.approx(0.5 * 1024 * 300.0 / 8000.0)        # 19.2 mm of a 38.4 mm field
    tilts = []
    for pose in stereo_calibration_views(spec, square, narrow, views):
        assert board_in_view(spec, square, narrow.left, pose)
        assert board_in_view(spec, square, narrow.right, narrow.right_pose(pose))
        for rvec in (pose.rvec, narrow.right_pose(pose).rvec):
            normal = cv2.Rodrigues(np.asarray(rvec))[0][:, 2]
            tilts.append(np.degrees(np.arccos(abs(normal[2]))))
    # each camera sees the board tilted 12.5-51.4 degrees from its axis (up to 37.5 from the bisector, and half the
    # rig's angle), the median 33: the steep views a long lens's focal length needs
    assert 45.0 < max(tilts) < 55.0 and 25.0 < np.median(tilts) < 40.0
