"""dic.noise_floor: the spatial and temporal SDs and the bias of static frames, on arrays of known statistics."""

import math

import numpy as np
import pytest

from livedic.dic.noise_floor import (NoiseFloor, NoiseFloorStatus, displacement_3d_noise_floor, field_noise_floor,
                                      noise_floor)


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


# --- stereo: U, V, W in the specimen's axes --------------------------------------------------------------------

def _tilted_plane(points: int, normal_deg: float):
    """Reference points on a plane whose normal is turned ``normal_deg`` about y from the camera's axis, and its
    specimen axes (rows: x, y, normal; the normal away from the camera at z = 300 mm)."""
    a = math.radians(normal_deg)
    e1, e2 = np.array([math.cos(a), 0, -math.sin(a)]), np.array([0.0, 1, 0])
    e3 = np.array([math.sin(a), 0, math.cos(a)])
    rng = np.random.default_rng(5)
    s, t = rng.uniform(-10, 10, (2, points))
    return np.array([0, 0, 300.0]) + s[:, None] * e1 + t[:, None] * e2, np.stack([e1, e2, e3])


def test_stereo_displacements_are_measured_in_the_specimen_axes_exactly():
    # U, V, W given in the specimen's axes and turned into the camera's: the floor gives back their exact SDs
    reference, axes = _tilted_plane(50, 20.0)
    rng = np.random.default_rng(6)
    in_specimen = rng.normal(0.0, [0.001, 0.002, 0.008], (6, 50, 3))
    displacement = in_specimen @ axes                  # rows of axes: specimen -> camera is axes.T @ q
    rows = {f.quantity: f for f in field_noise_floor(np.zeros((6, 50)), np.zeros((6, 50)), np.ones((6, 50), bool),
                                                     xyz_mm=reference + displacement, displacement_mm=displacement)}
    for i, name in enumerate(("U", "V", "W")):
        floor, values = rows[name], in_specimen[..., i]
        assert floor.unit == "mm" and floor.status is NoiseFloorStatus.OK
        assert floor.spatial_sd == pytest.approx(values.std(axis=1, ddof=1).mean(), rel=1e-9)
        assert floor.temporal_sd_mean == pytest.approx(values.std(axis=0, ddof=1).mean(), rel=1e-9)
        assert floor.temporal_sd_max == pytest.approx(values.std(axis=0, ddof=1).max(), rel=1e-9)
        assert floor.mean == pytest.approx(values.mean(), abs=1e-15)
    assert [f.quantity for f in rows.values()][:5] == ["u", "v", "U", "V", "W"]


def test_stereo_points_not_ok_do_not_count_and_too_few_give_no_plane():
    reference, axes = _tilted_plane(4, 0.0)
    displacement = np.zeros((2, 4, 3))
    displacement[1, :, 2] = [0.0, 0.002, 0.004, 0.002]            # W only (the normal is the camera's z)
    displacement[1, 3, 0] = 5.0                                     # a point not ok: its huge U never counts
    ok = np.array([[True, True, True, False], [True, True, True, False]])
    rows = displacement_3d_noise_floor(reference + displacement, displacement, ok)
    assert [r.points for r in rows] == [3, 3, 3] and rows[0].temporal_sd_max == pytest.approx(0.0, abs=1e-15)
    assert rows[2].temporal_sd_max == pytest.approx(0.004 / math.sqrt(2))
    ok[:, 2] = False                                                # two points left: no plane, NaN and why
    for row in displacement_3d_noise_floor(reference + displacement, displacement, ok):
        assert row.status is NoiseFloorStatus.NO_SPECIMEN_PLANE and math.isnan(row.temporal_sd_mean)
        assert "no specimen plane" in row.as_dict()["reason"]
    for row in displacement_3d_noise_floor(np.zeros((0, 4, 3)), np.zeros((0, 4, 3))):
        assert row.status is NoiseFloorStatus.TOO_FEW_FRAMES
    with pytest.raises(ValueError, match="3D points and displacements"):
        displacement_3d_noise_floor(np.zeros((2, 4, 2)), np.zeros((2, 4, 2)))
