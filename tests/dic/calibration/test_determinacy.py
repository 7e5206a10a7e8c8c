"""Tests of dic/calibration/determinacy.py: which parameters a set of flags fits, the narrow-field rule's decision
from the principal point's standard deviation, and a parameter's standard deviation as its effect at the corner."""

import math

import cv2
import numpy as np
import pytest

from livedic.dic.calibration.determinacy import (NARROW_FIELD_FIXED, NARROW_FIELD_FLAGS, PRINCIPAL_POINT_LIMIT,
                                                 UncertaintyBounds, corner_effects, free_parameters,
                                                 narrow_field_reason, undetermined)
from livedic.dic.calibration.solve import DEFAULT_FLAGS


def test_the_narrow_field_model_fits_the_focal_lengths_and_k1_only():
    assert free_parameters(DEFAULT_FLAGS) == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2")
    assert free_parameters(DEFAULT_FLAGS | NARROW_FIELD_FLAGS) == ("fx", "fy", "k1")
    assert set(NARROW_FIELD_FIXED) == {"cx", "cy", "k2", "p1", "p2"}


def test_the_principal_point_is_fixed_only_beyond_its_limit():
    limit = PRINCIPAL_POINT_LIMIT * 1024
    assert narrow_field_reason({"cx": 0.99 * limit, "cy": 0.5 * limit}, (1024, 768)) is None
    reason = narrow_field_reason({"cx": 2.0, "cy": 1.01 * limit}, (1024, 768))
    assert reason is not None and "principal point" in reason and f"+-{1.01 * limit:.1f} px" in reason


def test_a_distortion_terms_deviation_is_its_shift_of_the_farthest_corner():
    # f 1000 px, principal point at the centre of 1000 x 1000: the corner's normalised radius r = 0.7064; a radial
    # term k1 moves it by f k1 r^3, k2 by f k2 r^5 (to first order in sigma)
    K = np.array([[1000.0, 0.0, 499.5], [0.0, 1000.0, 499.5], [0.0, 0.0, 1.0]])
    r = math.hypot(499.5, 499.5) / 1000.0
    effects = corner_effects(K, np.zeros(5), (1000, 1000), {"fx": 5.0, "k1": 1e-4, "k2": 1e-4, "cx": 3.0})
    assert effects["fx"] == pytest.approx(0.5)                        # % of f
    assert effects["k1"] == pytest.approx(1000 * 1e-4 * r ** 3, rel=1e-3)
    assert effects["k2"] == pytest.approx(1000 * 1e-4 * r ** 5, rel=1e-3)
    assert "cx" not in effects                                        # bounded by the narrow-field rule instead


def test_parameters_above_their_bounds_are_named_worst_first():
    bounds = UncertaintyBounds(focal_percent=1.0, corner_px=2.0)
    over = undetermined({"fx": 3.0, "fy": 0.5, "k1": 3.0, "k2": float("nan")}, bounds)
    assert [name for name, _, _ in over] == ["k2", "fx", "k1"]       # NaN (a singular fit) first
    assert undetermined({"fx": 0.9, "k1": 1.9}, bounds) == []


def test_flags_name_what_opencv_holds_fixed():
    assert "k1" not in free_parameters(cv2.CALIB_FIX_K1) and "k3" not in free_parameters(cv2.CALIB_FIX_K3)
