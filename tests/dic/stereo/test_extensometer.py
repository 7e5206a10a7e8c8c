"""Tests of dic/stereo/extensometer.py: 3D extensometers on a tilted plane read L0 in mm exactly, a stretch along
their line exactly, zero under any rigid motion in space (which a 2D length does not), and a lost end as lost."""

import cv2
import numpy as np
import pytest

from livedic.dic.strain.extensometer import BAND, Extensometer, ExtensometerStatus, place_extensometers
from livedic.dic.stereo.extensometer import read_extensometers_3d


def _plane(points_px: np.ndarray) -> np.ndarray:
    """Left-view px -> 3D points (mm) on a plane tilted 30 degrees about x, 300 mm away, 0.1 mm a px."""
    tilt = cv2.Rodrigues(np.array([np.radians(30.0), 0.0, 0.0]))[0]
    local = np.column_stack([0.1 * (points_px - 250.0), np.zeros(len(points_px))])
    return local @ tilt.T + [0.0, 0.0, 300.0]


@pytest.mark.parametrize("end_fit", ["local", BAND])
def test_lengths_in_space_are_exact_for_stretch_and_blind_to_rigid_motion(end_fit):
    xs, ys = np.meshgrid(np.arange(100.0, 401.0, 10.0), np.arange(50.0, 451.0, 10.0))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    placed = place_extensometers([Extensometer("axial", 250.0, 100.0, 250.0, 400.0, end_fit),
                                  Extensometer("transverse", 150.0, 250.0, 350.0, 250.0, end_fit)], points, step=10.0)
    reference = _plane(points)
    ok = np.ones(len(points), dtype=bool)
    # 1 % along the axial line (the plane's own y), then a rigid turn of 2 degrees and 0.5 mm towards the camera
    centre = reference.mean(axis=0)
    tilt = cv2.Rodrigues(np.array([np.radians(30.0), 0.0, 0.0]))[0]
    along = tilt[:, 1]
    stretched = reference + 0.01 * ((reference - centre) @ along)[:, None] * along
    turn = cv2.Rodrigues(np.array([0.01, np.radians(2.0), -0.02]))[0]
    moved = (stretched - centre) @ turn.T + centre + [0.0, 0.0, -0.5]
    readings = read_extensometers_3d(placed, points, reference, ok, moved, ok)
    np.testing.assert_allclose(readings.l0_mm, [30.0, 20.0], rtol=1e-9)
    np.testing.assert_allclose(readings.eng_strain, [0.01, 0.0], atol=1e-9)
    assert np.all(readings.ok) and np.all(np.isnan(readings.l0_px))
    rigid = (reference - centre) @ turn.T + centre + [0.0, 0.0, -0.5]
    np.testing.assert_allclose(read_extensometers_3d(placed, points, reference, ok, rigid, ok).eng_strain, 0.0,
                               atol=1e-9)
    # the same rigid motion seen as the camera sees it (x/z, y/z: a 2D length) reads strain
    seen0, seen = reference[:, :2] / reference[:, 2:], rigid[:, :2] / rigid[:, 2:]
    a, b = (int(np.flatnonzero((points[:, 0] == 250.0) & (points[:, 1] == y))[0]) for y in (100.0, 400.0))
    axial2d = np.linalg.norm(seen[b] - seen[a]) / np.linalg.norm(seen0[b] - seen0[a]) - 1.0
    assert abs(axial2d) > 1e-3


def test_an_end_whose_band_is_lost_is_lost_not_frozen():
    xs, ys = np.meshgrid(np.arange(100.0, 401.0, 10.0), np.arange(50.0, 451.0, 10.0))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    placed = place_extensometers([Extensometer("axial", 250.0, 100.0, 250.0, 400.0)], points, step=10.0)
    reference = _plane(points)
    ok = np.ones(len(points), dtype=bool)
    now_ok = ok & (points[:, 1] > 150.0)        # every point around the first end lost
    readings = read_extensometers_3d(placed, points, reference, ok, reference, now_ok)
    assert readings.status[0] == ExtensometerStatus.END_LOST and np.isnan(readings.eng_strain[0])
    assert np.isnan(readings.length_mm[0]) and readings.l0_mm[0] == pytest.approx(30.0)
