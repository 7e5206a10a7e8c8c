"""Tests of the 3D simulator (coupon3d, stereo_render, stereo_scene): projections, rendering and truth checked against
OpenCV's projection, an independent inverse, finite differences and the pinhole camera's known 2D error."""

import cv2
import numpy as np
import pytest

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion
from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.stereo_scene import StereoScene

DISTANCE = 300.0
MOVING = dict(strain=0.05, neck=0.2, w0_mm=0.5, rot_x_deg=1.0, rot_y_deg=-1.5)


def small_scene(motion, *, facing="middle", distortion=(-0.3, 0.05, 1e-3, -5e-4), supersample=1, noise=0.0):
    """A 256 x 224 rig (focal 2000 px: 6.7 px/mm at 300 mm) with strong distortion, so the lens matters."""
    left = Lens((256, 224), *distortion, focal_px=2000.0)
    right = Lens((256, 224), *distortion, focal_px=2100.0)
    rig = StereoRig.symmetric(left, right, distance_mm=DISTANCE, angle_deg=25.0)
    return StereoScene(rig, Coupon(), motion, distance_mm=DISTANCE, facing=facing, radius_px=2.0, seed=3,
                       noise=noise, supersample=supersample)


MATERIAL = np.array([[0.0, 0.0], [6.0, 9.0], [-8.5, -12.0], [9.0, -4.0], [-3.0, 7.5]])


def test_projections_are_opencvs_of_the_3d_truth_and_cast_back_onto_the_same_material():
    scene = small_scene(CouponMotion(5, **MOVING))
    calibration = scene.rig.calibration()
    for frame in (0, 2, 4):
        truth = scene.truth(frame, MATERIAL)
        left, right = scene.project(frame, MATERIAL)
        expected_left, _ = cv2.projectPoints(truth.position_mm, np.zeros(3), np.zeros(3),
                                             calibration.left.camera_matrix, calibration.left.dist_coeffs)
        expected_right, _ = cv2.projectPoints(truth.position_mm, cv2.Rodrigues(calibration.rotation)[0],
                                              calibration.translation_mm, calibration.right.camera_matrix,
                                              calibration.right.dist_coeffs)
        np.testing.assert_allclose(left, expected_left.reshape(-1, 2), atol=1e-9)
        np.testing.assert_allclose(right, expected_right.reshape(-1, 2), atol=1e-9)
        # the ray through each projection meets the deformed surface at the material point again
        np.testing.assert_allclose(scene.material_at("left", frame, left), MATERIAL, atol=1e-8)
        np.testing.assert_allclose(scene.material_at("right", frame, right), MATERIAL, atol=1e-8)
        # the match lies on its epipolar line (ideal px: the lenses' distortion undone)
        ideal_left = scene.rig.left.undistort(left)
        ideal_right = scene.rig.right.undistort(right)
        lines = cv2.computeCorrespondEpilines(ideal_left.reshape(-1, 1, 2), 1, calibration.fundamental_matrix())
        lines = lines.reshape(-1, 3)
        distance = np.abs(np.sum(lines[:, :2] * ideal_right, axis=1) + lines[:, 2])
        assert np.max(distance) < 1e-6


@pytest.mark.parametrize("strain, neck", [(-0.3, 0.0), (0.05, 0.6)])
def test_the_coupons_edges_are_where_their_material_projects_in_compression_and_in_a_deep_neck(strain, neck):
    scene = small_scene(CouponMotion(2, strain=strain, neck=neck, w0_mm=-1.0, rot_y_deg=8.0))
    half = 0.5 * scene.coupon.width_mm
    Y0 = np.linspace(-8.0, 8.0, 9)
    for view, index in (("left", 0), ("right", 1)):
        for side in (-1.0, 1.0):
            inside = np.column_stack([np.full(Y0.shape, side * (half - 1e-6)), Y0])
            outside = np.column_stack([np.full(Y0.shape, side * (half + 1e-6)), Y0])
            np.testing.assert_allclose(scene.material_at(view, 1, scene.project(1, inside)[index]), inside, atol=1e-8)
            assert np.all(np.isnan(scene.material_at(view, 1, scene.project(1, outside)[index])))


def test_off_the_coupon_a_pixel_shows_no_material_and_the_background():
    scene = small_scene(CouponMotion(2))
    corner = scene.material_at("left", 0, np.array([[2.0, 2.0]]))
    assert np.all(np.isnan(corner))
    image = scene.clean("left", 0)
    assert image[2, 2] == pytest.approx(0.1 * 255, abs=1e-4)


def _material_by_projection(scene, view, frame, pixel):
    """The material point projecting onto ``pixel``, by Gauss-Newton on the forward model (OpenCV's projection):
    independent of the renderer's ray casting."""
    m = np.zeros(2)
    h = 1e-6
    for _ in range(30):
        f = scene.project_world(view, scene.positions(frame, m[None])).ravel() - pixel
        J = np.column_stack([(scene.project_world(view, scene.positions(frame, (m + d)[None])).ravel() - pixel - f) / h
                             for d in (np.array([h, 0.0]), np.array([0.0, h]))])
        step = np.linalg.solve(J, -f)
        m += step
        if np.max(np.abs(step)) < 1e-11:
            break
    return m


@pytest.mark.parametrize("view", ["left", "right"])
def test_a_rendered_pixel_shows_the_paint_of_the_material_point_projecting_onto_it(view):
    scene = small_scene(CouponMotion(3, **MOVING))
    frame = 2
    image = scene.clean(view, frame)
    rng = np.random.default_rng(1)
    checked = 0
    for x, y in rng.integers((90, 40), (170, 190), size=(12, 2)):
        material = _material_by_projection(scene, view, frame, np.array([x, y], dtype=float))
        if not scene.coupon.contains(*material):
            continue
        assert image[y, x] == pytest.approx(float(scene.grey_at(material[None])[0]), abs=2e-3)
        checked += 1
    assert checked >= 10
    # the camera's image: the clean one rounded (no noise asked for)
    np.testing.assert_array_equal(scene.render_view(view, frame), np.rint(image).astype(np.uint8))


def test_supersampling_averages_the_paint_over_the_pixel():
    one = small_scene(CouponMotion(2), supersample=1).clean("left", 0)
    four = small_scene(CouponMotion(2), supersample=2).clean("left", 0)
    # both sample the same smooth paint: they differ by its curvature over a pixel, not by a shift
    inside = (slice(60, 160), slice(100, 156))
    assert np.mean(np.abs(four[inside] - one[inside])) < 0.1 * np.std(one[inside])
    assert np.std(four[inside]) < np.std(one[inside])


def test_zero_motion_renders_identical_frames_and_every_motion_starts_from_the_same_reference():
    still = small_scene(CouponMotion(3, strain=0.0, neck=0.0))
    moving = small_scene(CouponMotion(3, **MOVING))
    for view in ("left", "right"):
        reference = still.clean(view, 0)
        np.testing.assert_array_equal(still.clean(view, 2), reference)
        np.testing.assert_array_equal(moving.clean(view, 0), reference)
        assert np.max(np.abs(moving.clean(view, 2) - reference)) > 50.0
    truth = still.truth(2, MATERIAL)
    assert np.max(np.abs(truth.displacement_mm)) == 0.0 and np.max(np.abs(truth.strain)) == 0.0


def test_the_surface_strain_is_the_green_lagrange_strain_of_the_3d_positions():
    scene = small_scene(CouponMotion(3, **MOVING))
    h = 1e-4
    for frame in (1, 2):
        truth = scene.truth(frame, MATERIAL)
        dX = (scene.positions(frame, MATERIAL + [h, 0.0]) - scene.positions(frame, MATERIAL - [h, 0.0])) / (2 * h)
        dY = (scene.positions(frame, MATERIAL + [0.0, h]) - scene.positions(frame, MATERIAL - [0.0, h])) / (2 * h)
        exx = 0.5 * (np.sum(dX * dX, axis=1) - 1.0)
        eyy = 0.5 * (np.sum(dY * dY, axis=1) - 1.0)
        exy = 0.5 * np.sum(dX * dY, axis=1)
        np.testing.assert_allclose(truth.strain, np.column_stack([exx, eyy, exy]), atol=1e-8)
    # the front surface recedes (+W, away from the cameras) by half the thickness lost: more in the neck
    still = small_scene(CouponMotion(3, strain=0.05, neck=0.2, w0_mm=0.5))
    W = still.truth(2, np.array([[0.0, 0.0], [0.0, 30.0]])).displacement_specimen_mm[:, 2]
    half = 0.5 * still.coupon.thickness_mm
    assert W[0] == pytest.approx(0.5 + half * (0.3 * 0.05 + 0.5 * 0.2), abs=1e-12)
    assert W[1] == pytest.approx(0.5 + half * 0.3 * 0.05, abs=1e-4)     # sech^2(30 / 5) ~ 2.5e-5


def test_an_out_of_plane_translation_seen_by_one_camera_is_an_apparent_strain_w0_over_distance():
    """The 2D error stereo removes: 0.5 mm away from a camera 300 mm off reads as -0.5 / 300.5 of strain."""
    w0 = 0.5
    scene = small_scene(CouponMotion(2, strain=0.0, neck=0.0, w0_mm=w0), facing="left", distortion=(0.0,) * 4)
    apparent = -w0 / (DISTANCE + w0)
    centre = scene.project(0, np.zeros((1, 2)))[0][0]
    h = 40.0
    x = centre[0] + np.array([-h, h, 0.0, 0.0])
    y = centre[1] + np.array([0.0, 0.0, -h, h])
    u, v = scene.image_displacement("left", 1, x, y)
    assert (u[1] - u[0]) / (2 * h) == pytest.approx(apparent, rel=1e-9)
    assert (v[3] - v[2]) / (2 * h) == pytest.approx(apparent, rel=1e-9)
    # in 3D there is no strain: the coupon only moved along its normal
    truth = scene.truth(1, MATERIAL)
    assert np.max(np.abs(truth.strain)) < 1e-15
    np.testing.assert_allclose(truth.displacement_specimen_mm, np.tile([0.0, 0.0, w0], (len(MATERIAL), 1)), atol=1e-12)


def test_the_rendered_images_show_that_apparent_strain():
    """Measured on the images themselves (OpenCV's ECC affine fit on the coupon), not read from the truth."""
    w0 = 3.0
    scene = small_scene(CouponMotion(2, strain=0.0, neck=0.0, w0_mm=w0), facing="left", distortion=(0.0,) * 4)
    before, after = scene.clean("left", 0), scene.clean("left", 1)
    mask = np.zeros(before.shape, np.uint8)
    mask[30:-30, 75:181] = 1          # the coupon (x 61..195) but its edges
    warp = np.eye(2, 3, dtype=np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-8)
    _, warp = cv2.findTransformECC(before, after, warp, cv2.MOTION_AFFINE, criteria, mask, 1)
    apparent = -w0 / (DISTANCE + w0)
    assert warp[0, 0] - 1.0 == pytest.approx(apparent, abs=3e-4)
    assert warp[1, 1] - 1.0 == pytest.approx(apparent, abs=3e-4)
