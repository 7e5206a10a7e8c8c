"""Tests of dic/stereo/surface_strain.py and frame.py on exact projections: rigid motions in space give zero
surface strain, an in-plane stretch of a tilted plane gives its strain, the 2D error stereo removes is there."""

import math

import cv2
import numpy as np
import pytest

from livedic.dic.stereo import (StereoMatch, StereoStatus, extensometer_3d, project, specimen_frame, stereo_points,
                                surface_strain, surface_window, triangulate)
from livedic.dic.strain import StrainStatus, strain_field, strain_window
from tests.dic.stereo.rig import DISTANCE_MM, board_of_left, facing_pose, grid, moved, rig, world

STEP = 20


def exact_reference(stereo, pose, points):
    """The reference pair's match made from exact projections (what match_stereo finds to ~0.003 px)."""
    calibration = stereo.calibration()
    board = board_of_left(stereo, pose, points)
    left, right = project(calibration, world(pose, board))
    triangulation = triangulate(calibration, left, right)
    return board, StereoMatch(left=left, right=right, gradients=np.zeros((len(left), 4)), zncc=np.ones(len(left)),
                              triangulation=triangulation, status=triangulation.status,
                              match_status=np.zeros(len(left), dtype=np.int8))


def frame_of(stereo, reference, current_xyz, noise_px=0.0, seed=0):
    calibration = stereo.calibration()
    left, right = project(calibration, current_xyz)
    rng = np.random.default_rng(seed)
    left, right = left + rng.normal(0, noise_px, left.shape), right + rng.normal(0, noise_px, right.shape)
    ok = np.ones(len(left), dtype=bool)
    return left, stereo_points(calibration, reference, left, ok, right, ok)


@pytest.fixture(scope="module")
def scene():
    stereo = rig()
    pose = facing_pose(stereo, tilt_deg=20.0)         # a plane tilted 20 degrees to the rig, as well
    points = grid(STEP)
    board, reference = exact_reference(stereo, pose, points)
    return stereo, pose, points, board, reference, surface_window(points, reference.xyz)


def test_a_rigid_motion_in_space_gives_its_displacements_and_no_surface_strain(scene):
    """Turned 1 degree about a tilted axis and moved 0.5 mm towards the cameras: U, V, W exact, strain zero."""
    stereo, pose, points, board, reference, window = scene
    now = moved(pose, (0.012, math.radians(1.0), 0.004), (0.2, -0.3, -0.5))
    _, frame = frame_of(stereo, reference, world(now, board))
    assert np.all(frame.ok)
    np.testing.assert_allclose(frame.displacement, world(now, board) - world(pose, board), atol=1e-6)
    strain = surface_strain(window, reference.xyz, frame.xyz, frame.ok)
    assert np.all(strain.ok)
    for component in (strain.exx, strain.eyy, strain.exy):
        assert np.max(np.abs(component)) < 1e-9


def test_an_in_plane_stretch_of_a_tilted_plane_reads_its_strain_and_nothing_from_the_tilt(scene):
    """1 % along the board's x, 0.3 % across, on a plane tilted to both cameras: Green-Lagrange principal
    strains (1.01^2 - 1)/2 and (1.003^2 - 1)/2 everywhere to 1e-9; with 0.02 px of image noise to 5e-4."""
    stereo, pose, points, board, reference, window = scene
    current = world(pose, board * [1.01, 1.003])
    _, frame = frame_of(stereo, reference, current)
    strain = surface_strain(window, reference.xyz, frame.xyz, frame.ok)
    assert np.all(strain.ok)
    np.testing.assert_allclose(strain.e1, (1.01 ** 2 - 1) / 2, atol=1e-9)
    np.testing.assert_allclose(strain.e2, (1.003 ** 2 - 1) / 2, atol=1e-9)
    _, noisy = frame_of(stereo, reference, current, noise_px=0.02)
    strain = surface_strain(window, reference.xyz, noisy.xyz, noisy.ok)
    assert np.nanmean(np.abs(strain.e1 - (1.01 ** 2 - 1) / 2)) < 5e-4
    # the 3D extensometer across the field reads the stretch along the board's x
    left_end, right_end = np.argmin(board[:, 0]), np.argmax(board[:, 0])
    reading = extensometer_3d(reference.xyz, frame.xyz, [[left_end, right_end]])
    assert reading.strain[0] == pytest.approx(np.linalg.norm(((board[right_end] - board[left_end]) * [1.01, 1.003]))
                                              / np.linalg.norm(board[right_end] - board[left_end]) - 1, abs=1e-9)


def test_out_of_plane_translation_gives_no_surface_strain_where_2d_reads_w_over_distance():
    """0.5 mm towards the cameras: the left image alone shows a uniform 2D strain of +0.5/300 (the 2D
    measurement's error, W / distance); on the surface it is zero."""
    stereo = rig()
    pose = facing_pose(stereo)
    points = grid(STEP)
    board, reference = exact_reference(stereo, pose, points)
    normal = cv2.Rodrigues(pose.rvec)[0][:, 2]
    now = moved(pose, translation_mm=-0.5 * normal)
    left, frame = frame_of(stereo, reference, world(now, board))
    strain = surface_strain(surface_window(points, reference.xyz), reference.xyz, frame.xyz, frame.ok)
    assert np.max(np.abs(np.concatenate([strain.exx, strain.eyy, strain.exy]))) < 1e-9
    apparent = strain_field(strain_window(points), *(left - points).T, np.ones(len(points), dtype=bool))
    assert np.median(apparent.exx) == pytest.approx(0.5 / DISTANCE_MM, rel=0.15)
    # in the specimen's frame the whole motion is W, along the plane's normal
    turned = specimen_frame(reference.xyz).turn(frame.displacement)
    np.testing.assert_allclose(turned, [[0.0, 0.0, -0.5]] * len(turned), atol=1e-6)


def test_flags_pass_through_the_frame_and_the_strain(scene):
    """A point lost in one view is NaN with that view's reason; its neighbours keep their strain; a point whose
    window has lost most of its points has none (the 2D strain's rules)."""
    stereo, pose, points, board, reference, window = scene
    calibration = stereo.calibration()
    left, right = project(calibration, world(pose, board * [1.01, 1.0]))
    left_ok = np.ones(len(points), dtype=bool)
    right_ok = left_ok.copy()
    centre = int(np.argmin(np.linalg.norm(points - points.mean(axis=0), axis=1)))
    left_ok[centre] = False
    right_ok[centre + 1] = False
    right[centre + 2, 1] += 3.0                       # a track that slipped off the epipolar line
    corner = np.linalg.norm(points - points[0], axis=1) <= 2 * STEP * 1.5
    right_ok[corner & (np.arange(len(points)) != 0)] = False
    frame = stereo_points(calibration, reference, left, left_ok, right, right_ok)
    assert frame.status[centre] == StereoStatus.LEFT_NOT_OK
    assert frame.status[centre + 1] == StereoStatus.RIGHT_NOT_OK
    assert frame.status[centre + 2] == StereoStatus.EPIPOLAR
    assert np.all(np.isnan(frame.displacement[[centre, centre + 1, centre + 2]]))
    strain = surface_strain(window, reference.xyz, frame.xyz, frame.ok)
    assert strain.status[centre] == StrainStatus.POINT_NOT_OK and np.isnan(strain.exx[centre])
    assert strain.status[0] == StrainStatus.TOO_FEW_POINTS and np.isnan(strain.e1[0])
    neighbour = centre - len(np.unique(points[:, 0]))        # the point above the centre
    assert strain.ok[neighbour]
    assert strain.e1[neighbour] == pytest.approx((1.01 ** 2 - 1) / 2, abs=1e-9)


def test_unmatched_reference_points_stay_flagged_in_every_frame(scene):
    stereo, pose, points, board, reference, window = scene
    status = reference.status.copy()
    status[3] = StereoStatus.LOW_CORRELATION
    bad = StereoMatch(reference.left, reference.right, reference.gradients, reference.zncc, reference.triangulation,
                      status, reference.match_status)
    _, frame = frame_of(stereo, bad, reference.xyz)
    assert frame.status[3] == StereoStatus.LOW_CORRELATION and np.all(np.isnan(frame.xyz[3]))
    assert np.sum(frame.ok) == len(points) - 1


def test_bad_inputs_are_refused(scene):
    stereo, pose, points, board, reference, window = scene
    with pytest.raises(ValueError, match="strain measure"):
        surface_strain(window, reference.xyz, reference.xyz, reference.ok, measure="cauchy")
    with pytest.raises(ValueError, match="surface window holds"):
        surface_strain(window, reference.xyz[:-1], reference.xyz[:-1], reference.ok[:-1])
    with pytest.raises(ValueError, match="reference holds"):
        stereo_points(stereo.calibration(), reference, reference.left, reference.ok[:-1], reference.right, reference.ok)
    with pytest.raises(ValueError, match="point indices"):
        extensometer_3d(reference.xyz, reference.xyz, [[0, len(points)]])
