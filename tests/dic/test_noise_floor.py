"""dic.noise_floor: the spatial and temporal SDs and the bias of static frames, on arrays of known statistics."""

import math

import numpy as np
import pytest

from livedic.dic.noise_floor import NoiseFloor, NoiseFloorStatus, field_noise_floor, noise_floor


def test_white_noise_gives_its_sigma_both_ways_and_zero_bias():
    rng = np.random.default_rng(1)
    sigma = 0.02
    values = rng.normal(0.0, sigma, (40, 2000))
    floor = noise_floor(values, quantity="u", unit="px")
    assert floor.status is NoiseFloorStatus.OK
    assert floor.spatial_sd == pytest.approx(sigma, rel=0.02)
    assert floor.temporal_sd_mean == pytest.approx(sigma, rel=0.02)
    assert sigma < floor.temporal_sd_max < 2 * sigma
    assert abs(floor.mean) < 5 * sigma / math.sqrt(values.size)
    assert (floor.frames, floor.points, floor.values) == (40, 2000, 80000)


def test_a_fixed_pattern_error_shows_in_the_spatial_sd_only():
    # each point's own constant error (a systematic, pattern-induced bias) does not change with time
    rng = np.random.default_rng(2)
    offsets = rng.normal(0.0, 0.03, 3000)
    values = 0.5 + offsets[None, :] + rng.normal(0.0, 0.01, (30, 3000))
    floor = noise_floor(values, quantity="v", unit="px")
    assert floor.spatial_sd == pytest.approx(math.hypot(0.03, 0.01), rel=0.04)
    assert floor.temporal_sd_mean == pytest.approx(0.01, rel=0.03)
    assert floor.mean == pytest.approx(0.5, abs=0.003)


def test_exact_values_with_excluded_points_and_nan():
    values = np.array([[0.0, 2.0, 100.0, np.nan],
                       [2.0, 4.0, -100.0, 7.0]])
    ok = np.array([[True, True, False, True],
                   [True, True, False, True]])
    floor = noise_floor(values, ok, quantity="exx", unit="microstrain", factor=10.0)
    # frame 0: {0, 20}, frame 1: {20, 40, 70}; point 3 has one finite value: no temporal SD
    assert floor.spatial_sd == pytest.approx((np.std([0, 20], ddof=1) + np.std([20, 40, 70], ddof=1)) / 2)
    assert floor.temporal_sd_mean == pytest.approx(np.std([0, 20], ddof=1))
    assert floor.temporal_sd_max == pytest.approx(np.std([0, 20], ddof=1))
    assert floor.mean == pytest.approx((0 + 20 + 20 + 40 + 70) / 5)
    assert (floor.points, floor.values) == (2, 5)


def test_one_frame_gives_the_spatial_sd_and_says_the_temporal_one_is_missing():
    values = np.array([[0.0, 2.0, 4.0]])
    floor = noise_floor(values, quantity="u", unit="px")
    assert floor.status is NoiseFloorStatus.SPATIAL_ONLY and not floor.ok
    assert floor.spatial_sd == pytest.approx(2.0) and floor.mean == pytest.approx(2.0)
    assert math.isnan(floor.temporal_sd_mean) and math.isnan(floor.temporal_sd_max) and floor.points == 0
    assert floor.as_dict()["reason"].startswith("one static frame")


def test_no_frame_is_nan_with_its_reason():
    floor = noise_floor(np.zeros((0, 10)), quantity="u", unit="px")
    assert floor.status is NoiseFloorStatus.TOO_FEW_FRAMES and not floor.ok
    assert all(math.isnan(x) for x in (floor.spatial_sd, floor.temporal_sd_mean, floor.temporal_sd_max, floor.mean))
    assert floor.as_dict()["reason"] == "no static frame"


def test_no_ok_value_is_nan_with_its_reason():
    floor = noise_floor(np.ones((5, 3)), np.zeros((5, 3), bool), quantity="u", unit="px")
    assert floor.status is NoiseFloorStatus.NO_OK_VALUES and math.isnan(floor.spatial_sd)


def test_a_single_point_has_a_temporal_sd_only():
    strain = np.array([1e-5, -1e-5, 3e-5, -3e-5])
    floor = noise_floor(strain, [True, True, True, False], quantity="axial", unit="microstrain", factor=1e6)
    assert floor.ok and math.isnan(floor.spatial_sd)
    assert floor.temporal_sd_mean == pytest.approx(np.std([10, -10, 30], ddof=1))
    assert floor.mean == pytest.approx(10.0)


def test_the_table_has_mm_with_a_scale_and_round_trips_through_its_dict():
    rng = np.random.default_rng(3)
    u, v = rng.normal(0, 0.02, (2, 6, 50))
    ok = np.ones((6, 50), bool)
    exx = rng.normal(0, 1e-4, (6, 50))
    table = field_noise_floor(u, v, ok, exx=exx, eyy=exx, exy=exx, scale_px_per_mm=10.0,
                              extensometers={"axial": (exx[:, 0], ok[:, 0])})
    assert [(f.quantity, f.unit) for f in table] == [
        ("u", "px"), ("v", "px"), ("u", "mm"), ("v", "mm"), ("exx", "microstrain"), ("eyy", "microstrain"),
        ("exy", "microstrain"), ("axial", "microstrain")]
    assert table[2].temporal_sd_mean == pytest.approx(table[0].temporal_sd_mean / 10.0)
    assert table[4].spatial_sd == pytest.approx(1e6 * np.mean(np.std(exx, axis=1, ddof=1)))
    for floor in table:
        back = NoiseFloor.from_dict(floor.as_dict())
        assert back.as_dict() == floor.as_dict()
