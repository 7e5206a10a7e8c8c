"""Tests of acquire/simulator/targets.py: calibration targets rendered through a known lens at known poses."""

import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.targets import (board_extent, calibration_views, plane_view, pose_homography,
                                               render_target)
from livedic.dic.calibration import Detection, detect_target, parse_target

SIZE = (384, 384)


def _seen(lens, pose, spec, square):
    """Where the board's corners are in the image: through the pose's homography, then the lens."""
    H = pose_homography(lens, pose)
    board = spec.object_points(square)[:, :2]
    ideal = np.c_[board, np.ones(len(board))] @ H.T
    return lens.distort(ideal[:, :2] / ideal[:, 2:])


@pytest.mark.parametrize("k1", [0.0, -0.12])
def test_the_rendered_corners_are_found_where_the_pose_and_lens_put_them(k1):
    lens = Lens(SIZE, k1=k1)
    spec = parse_target("chessboard:7x5")
    pose = calibration_views(spec, 8.0, lens)[1]                # a tilted view
    found = detect_target(render_target(spec, 8.0, lens, pose, noise=0.5, seed=3), spec, 8.0)
    assert isinstance(found, Detection)
    seen = _seen(lens, pose, spec, 8.0)
    # a chessboard is symmetric under a half turn: OpenCV may number its corners from either end
    error = min((np.hypot(*(found.image_points - order).T) for order in (seen, seen[::-1])), key=np.max)
    # the image holds its truth to what the corner detector resolves (its reprojection RMS: 0.05-0.1 px)
    assert np.sqrt(np.mean(error ** 2)) < 0.12 and error.max() < 0.4, error


def test_a_plane_view_shows_the_asked_scale_at_the_centre_and_its_tilt_foreshortens_y():
    lens = Lens(SIZE)
    spec = parse_target("chessboard:7x5")
    flat = pose_homography(lens, plane_view(spec, 5.0, lens, 4.0))
    tilted = pose_homography(lens, plane_view(spec, 5.0, lens, 4.0, tilt_deg=20.0))
    centre = spec.object_points(5.0)[:, :2].mean(axis=0)

    def scale(H, direction):
        a, b = np.r_[centre, 1.0], np.r_[centre + direction * 1e-3, 1.0]
        pa, pb = H @ a, H @ b
        return np.hypot(*(pb[:2] / pb[2] - pa[:2] / pa[2])) / 1e-3
    assert scale(flat, np.array([1.0, 0.0])) == pytest.approx(4.0, rel=1e-9)
    assert scale(flat, np.array([0.0, 1.0])) == pytest.approx(4.0, rel=1e-9)
    assert scale(tilted, np.array([0.0, 1.0])) == pytest.approx(4.0 * np.cos(np.radians(20.0)), rel=0.02)


def test_the_board_extent_has_a_square_of_white_around_the_corners():
    x0, y0, x1, y1 = board_extent(parse_target("chessboard:9x6"), 2.0)
    assert (x0, y0, x1, y1) == (-4.0, -4.0, 20.0, 14.0)          # corners 0..16 x 0..10 mm, a square + margin
