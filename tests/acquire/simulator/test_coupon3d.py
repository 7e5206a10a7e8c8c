"""Tests of acquire/simulator/coupon3d.py: the coupon's motion and its exact surface strain, analytically."""

import numpy as np
import pytest

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion


def test_uniform_strain_and_rigid_motion_give_the_green_strain_of_the_stretch_alone():
    """1 % axial strain (lateral -0.3 %), turned 2 degrees and moved 0.5 mm: every material segment's length
    follows the Green strain; the rigid part changes no length."""
    coupon = Coupon()
    motion = CouponMotion(frames=3, strain=0.01, neck=0.0, w0_mm=0.5, rot_x_deg=2.0, rot_y_deg=-1.0)
    state = motion.state(2)
    X0, Y0 = np.meshgrid(np.linspace(-8, 8, 5), np.linspace(-30, 30, 7))
    strain = coupon.strain(state, X0, Y0)
    e = 0.01
    lateral = 1.0 - 0.3 * e
    np.testing.assert_allclose(strain[..., 0], 0.5 * (lateral ** 2 - 1.0), atol=1e-15)
    np.testing.assert_allclose(strain[..., 1], 0.5 * ((1 + e) ** 2 - 1.0), atol=1e-15)
    np.testing.assert_allclose(strain[..., 2], 0.0, atol=1e-15)
    # lengths in space of an axial segment agree with the axial Green strain
    a, b = coupon.surface(state, 0.0, -10.0), coupon.surface(state, 0.0, 10.0)
    assert np.linalg.norm(b - a) == pytest.approx(20.0 * (1 + e), rel=1e-12)
    centre = coupon.surface(state, 0.0, 0.0)
    # the centre: moved 0.5 mm along z, its surface receded by half the thickness lost, along the turned normal
    recess = 0.5 * coupon.thickness_mm * 0.3 * e
    np.testing.assert_allclose(centre, state.rotation[:, 2] * recess + [0.0, 0.0, 0.5], atol=1e-12)
    assert motion.tau(0) == 0.0 and motion.tau(2) == 1.0


def test_the_neck_thins_the_front_surface_and_adds_its_slope_to_the_axial_strain():
    coupon = Coupon()
    state = CouponMotion(frames=2, strain=0.0, neck=0.2).state(1)
    front = coupon.surface(state, 0.0, np.array([-30.0, 0.0]))
    assert front[1, 2] > front[0, 2] + 0.01            # the front surface recedes (z grows) at the neck's centre
    Y0, h = 3.0, 1e-5
    dy = (coupon.surface(state, 0.0, Y0 + h) - coupon.surface(state, 0.0, Y0 - h)) / (2 * h)
    assert coupon.strain(state, 0.0, Y0)[1] == pytest.approx(0.5 * (dy @ dy - 1.0), rel=1e-8)
    with pytest.raises(ValueError, match="frames >= 2"):
        CouponMotion(frames=1)
