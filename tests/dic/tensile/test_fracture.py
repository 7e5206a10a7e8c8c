"""Fracture detection (``dic.tensile.fracture``): a band lost at once AND a jump across it; neither alone."""

import numpy as np
import pytest

from livedic.dic.tensile.fracture import detect_fracture

STEP = 10.0
XS, YS = np.meshgrid(np.arange(100.0, 400.0, STEP), np.arange(100.0, 600.0, STEP))
X, Y = XS.ravel(), YS.ravel()
CRACK_Y = 350.0


def frame(shift_top=0.0, lost=None):
    """ok, u, v: the part above the crack (smaller y) moved up by ``shift_top`` px; ``lost`` not ok."""
    ok = np.ones(X.size, dtype=bool) if lost is None else ~lost
    u = np.where(ok, 0.01 * (X - 250), np.nan)
    v = np.where(ok, 0.02 * (Y - 600) - np.where(Y < CRACK_Y, shift_top, 0.0), np.nan)
    return ok, u, v


def detect(before, now, trackable=None):
    return detect_fracture(X, Y, before[0], now[0], before[1], before[2], now[1], now[2], step=STEP, subset=21,
                           trackable=trackable)


BAND = np.abs(Y - CRACK_Y) < 12          # the subsets straddling the crack: two rows of points


def test_a_band_lost_with_a_jump_is_a_fracture():
    fracture = detect(frame(), frame(shift_top=4.0, lost=BAND))
    assert fracture is not None
    assert fracture.lost == BAND.sum()
    assert fracture.jump_px == pytest.approx(4.0, abs=1e-9)
    assert abs(fracture.direction[1]) < 1e-9                   # along x: a crack across the coupon
    assert fracture.centre[1] == pytest.approx(CRACK_Y)
    separated = fracture.separated
    assert separated[BAND].all() and not separated[np.abs(Y - CRACK_Y) > 21].any()
    assert set(np.unique(fracture.side[~separated])) == {-1, 1}
    assert "fracture" in fracture.describe()


def test_a_band_lost_without_a_jump_is_not_a_fracture():
    """Something passing in front of the camera: points lost along a line, nothing moved apart."""
    assert detect(frame(), frame(lost=BAND)) is None


def test_a_jump_without_a_band_is_not_a_fracture():
    """A grip slip moves a whole part but loses no band of points."""
    assert detect(frame(), frame(shift_top=4.0)) is None


def test_scattered_losses_are_not_a_band():
    rng = np.random.default_rng(0)
    scattered = np.zeros(X.size, dtype=bool)
    scattered[rng.choice(X.size, BAND.sum(), replace=False)] = True
    assert detect(frame(), frame(shift_top=4.0, lost=scattered)) is None


def test_a_short_band_is_not_a_fracture():
    """A few lost points in a row at one edge (a local flake), not across the specimen."""
    short = BAND & (X < 140)
    assert detect(frame(), frame(shift_top=4.0, lost=short)) is None


def test_points_already_lost_do_not_count():
    before = frame(lost=BAND)
    assert detect(before, frame(shift_top=4.0, lost=BAND)) is None


def test_a_band_sliding_along_itself_is_not_a_fracture():
    """A specimen's edge moving past a static background: the edge's points lost at once, the specimen
    side moving along the edge (the load axis), the background side still: a boundary, not a crack."""
    edge_x = 250.0
    band = np.abs(X - edge_x) < 12
    ok = ~band
    u_before, v_before = np.zeros(X.size), np.where(X < edge_x, -20.0, 0.0)
    v_now = np.where(X < edge_x, -24.0, 0.0)                  # the specimen (left) moved 4 px along y
    now = (ok, np.where(ok, 0.0, np.nan), np.where(ok, v_now, np.nan))
    before = (np.ones(X.size, dtype=bool), u_before, v_before)
    assert detect(before, now) is None


def test_a_shear_crack_at_45_degrees_opens_enough():
    """A crack at 45 degrees with the upper part pulled along the load axis (y) still opens it."""
    distance = (X - 250.0) - (Y - 350.0)                       # the line y - 350 = x - 250
    band = np.abs(distance) / np.sqrt(2.0) < 8
    upper = distance > 0
    before = (np.ones(X.size, dtype=bool), np.zeros(X.size), np.zeros(X.size))
    ok = ~band
    now = (ok, np.where(ok, 0.0, np.nan), np.where(ok, np.where(upper, -4.0, 0.0), np.nan))
    fracture = detect(before, now)
    assert fracture is not None and fracture.jump_px == pytest.approx(4.0)
