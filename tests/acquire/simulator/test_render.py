"""Tests of acquire/simulator/render.py: the painted coupon on its background, camera noise and quantisation."""

import numpy as np
import pytest

from livedic.acquire.simulator.render import PAINT_FLOOR, PAINT_GAIN, paint, quantise, render_specimen

H, W = 6, 20


def _render(left, right, row_cover=1.0, xs=(), ys=(), amp=None, background=30.0, full=255.0):
    """One coupon of undeformed rows (X = column, Y = row) between ``left`` and ``right`` on ``background``."""
    xs, ys = np.asarray(xs, np.float64), np.asarray(ys, np.float64)
    amp = np.ones(xs.size) if amp is None else np.asarray(amp, np.float64)
    out = np.empty((H, W), np.float32)
    render_specimen(xs, ys, amp, 2.0, 8.0, np.arange(H, dtype=np.float64), np.zeros(H), np.ones(H),
                    np.full(H, float(left)), np.full(H, float(right)), np.full(H, float(row_cover)),
                    np.full(H, background), full, PAINT_FLOOR, PAINT_GAIN, out)
    return out


def test_bare_paint_inside_the_edges_background_outside_and_a_one_pixel_ramp():
    out = _render(left=5.0, right=14.0)
    bare = 255.0 * (PAINT_FLOOR + PAINT_GAIN)                    # no speckle: I = 0
    assert np.allclose(out[:, 6:14], bare, rtol=1e-6) and np.all(out[:, :4] == 30.0) and np.all(out[:, 16:] == 30.0)
    np.testing.assert_allclose(out[0, [4, 5, 14, 15]], [30.0, 30 + 0.5 * (bare - 30), 30 + 0.5 * (bare - 30), 30.0],
                               rtol=1e-6)


def test_a_crack_row_is_background_and_a_partly_covered_row_is_blended():
    assert np.all(_render(5.0, 14.0, row_cover=0.0) == 30.0)
    half = _render(5.0, 14.0, row_cover=0.5)
    bare = 255.0 * (PAINT_FLOOR + PAINT_GAIN)
    np.testing.assert_allclose(half[:, 10], 30 + 0.5 * (bare - 30), rtol=1e-6)


def test_one_speckle_darkens_the_paint_as_the_gaussian_sum_says():
    out = _render(0.0, W - 1.0, xs=[10.0], ys=[3.0])
    expected = 255.0 * (PAINT_FLOOR + PAINT_GAIN * np.exp(-np.exp(-((np.arange(W) - 10.0) ** 2) / 4.0)))
    np.testing.assert_allclose(out[3, 1:W - 1], expected[1:W - 1], rtol=1e-5)
    assert out[3, 10] == out.min() and paint(np.float64(1.0), 255.0) == pytest.approx(out[3, 10], rel=1e-5)
    faded = _render(0.0, W - 1.0, xs=[10.0], ys=[3.0], amp=[0.0])
    assert np.allclose(faded[:, 2:W - 2], 255.0 * (PAINT_FLOOR + PAINT_GAIN), rtol=1e-6)   # a faded spot is gone


def test_paint_spans_floor_to_floor_plus_gain():
    assert paint(np.array(0.0), 4095.0) == pytest.approx(4095.0 * (PAINT_FLOOR + PAINT_GAIN))
    assert paint(np.array(50.0), 4095.0) == pytest.approx(4095.0 * PAINT_FLOOR)


def test_quantise_rounds_and_clips_to_the_bit_depth():
    image = np.array([[-5.0, 0.4, 0.6, 254.5], [300.0, 4095.6, 1000.2, 3.5]], np.float32)
    eight = quantise(image, 8, 0.0, 0)
    assert eight.dtype == np.uint8 and eight.tolist() == [[0, 0, 1, 254], [255, 255, 255, 4]]    # rint: half to even
    twelve = quantise(image, 12, 0.0, 0)
    assert twelve.dtype == np.uint16 and twelve.tolist() == [[0, 0, 1, 254], [300, 4095, 1000, 4]]


def test_noise_is_seeded_with_the_stated_sigma():
    flat = np.full((64, 64), 2000.0, np.float32)
    a, b, c = (quantise(flat, 12, 5.0, seed) for seed in (3, 3, 4))
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert abs(a.mean() - 2000.0) < 0.5 and a.std() == pytest.approx(5.0, rel=0.1)
