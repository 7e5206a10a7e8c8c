"""Tests of acquire/simulator/stereo_render.py: the ray cast finds the material point a camera sees, exactly."""

import numpy as np

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion
from livedic.acquire.simulator.stereo_render import material_grid, ray_frame


def test_a_projected_material_point_casts_back_onto_itself_and_the_background_is_nan():
    """A camera 300 mm in front of the coupon (its axis along the coupon's normal): the ideal pixel of a material
    point of the stretched, turned coupon casts back to that point; a pixel beside the coupon sees nothing."""
    coupon = Coupon()
    state = CouponMotion(frames=2, strain=0.02, rot_x_deg=3.0, w0_mm=0.4).state(1)
    K = np.array([[3000.0, 0.0, 512.0], [0.0, 3000.0, 512.0], [0.0, 0.0, 1.0]])
    rotation, translation = np.eye(3), np.zeros(3)
    origin, M = ray_frame(rotation, translation, np.eye(3), np.array([0.0, 0.0, 300.0]), state)
    material = np.array([[2.0, -5.0], [-7.5, 12.0], [0.0, 0.0]])
    world = coupon.surface(state, material[:, 0], material[:, 1]) + [0.0, 0.0, 300.0]
    ideal = (world @ K.T)[:, :2] / world[:, 2:]
    seen = material_grid(ideal, K, origin, M, coupon, state)
    np.testing.assert_allclose(seen, material, atol=1e-8)
    beside = material_grid(np.array([[5.0, 512.0]]), K, origin, M, coupon, state)    # 50 mm off the axis
    assert np.isnan(beside).all()
