"""Classic surface fit on exact simulated speckle (dic.speckle), and the rules it shares with the improved one."""

import numpy as np
import pytest

from livedic.dic.speckle import render
from livedic.dic.status import Status
from livedic.dic.subpixel import improved_surface_fit, surface_fit
from tests.dic.subpixel.conftest import HALF, SIZE, integer_start, refine_with


@pytest.mark.parametrize("shift", [(0.3, -0.2), (0.5, 0.5), (-0.8, 0.1), (1.4, -1.7)])
def test_surface_fit_recovers_subpixel_shifts_within_its_bound(pattern, reference, points, shift):
    deformed = render(pattern, shift).astype(np.float32)
    found = integer_start(reference, deformed, points)
    r = refine_with(surface_fit, reference, deformed, points, found)
    assert np.all(r.status == Status.OK)
    err_u, err_v = r.u - shift[0], r.v - shift[1]
    assert abs(err_u.mean()) < 0.02 and abs(err_v.mean()) < 0.02
    assert np.percentile(np.hypot(err_u, err_v), 95) < 0.1
    assert np.all(np.abs(err_u) < 0.3) and np.all(np.abs(err_v) < 0.3)


def test_other_status_codes_are_copied_through(pattern, reference, points):
    deformed = render(pattern, (0.5, 0.25)).astype(np.float32)
    found = integer_start(reference, deformed, points)
    status = found.status.copy()
    status[::3] = Status.LOW_CORRELATION
    xs, ys = points
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(reference, deformed, xs, ys, found.u.astype(float), found.v.astype(float), status, HALF)
        assert np.all(r.status[::3] == Status.LOW_CORRELATION)
        assert np.all(np.isnan(r.u[::3])) and np.all(np.isnan(r.v[::3]))
        assert np.all(r.status[1::3] == Status.OK) and np.all(np.isfinite(r.u[1::3]))


def test_peaks_against_the_image_edge_are_flagged_not_extrapolated(pattern, reference):
    # the true peak lies towards the image edge and the nodes needed to bracket it would leave the image
    deformed = render(pattern, (-0.3, 0.3)).astype(np.float32)
    xs = np.array([HALF, 128, 128], dtype=np.int64)
    ys = np.array([128, SIZE - 1 - HALF, 128], dtype=np.int64)
    zero = np.zeros(3)
    ok = np.zeros(3, dtype=np.int8)
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(reference, deformed, xs, ys, zero, zero, ok, HALF)
        assert list(r.status) == [Status.OUTSIDE_TARGET, Status.OUTSIDE_TARGET, Status.OK]
        assert np.all(np.isnan(r.u[:2])) and np.all(np.isnan(r.v[:2]))
        assert r.u[2] == pytest.approx(-0.3, abs=0.1) and r.v[2] == pytest.approx(0.3, abs=0.1)


def test_flat_reference_and_bad_start(reference):
    flat = np.full((64, 64), 50.0, dtype=np.float32)
    xs = np.array([32, 32], dtype=np.int64)
    ys = np.array([32, 32], dtype=np.int64)
    u0 = np.array([0.0, np.nan])
    for module in (surface_fit, improved_surface_fit):
        r = module.refine(flat, flat, xs, ys, u0, np.zeros(2), np.zeros(2, dtype=np.int8), HALF)
        assert list(r.status) == [Status.FLAT_REFERENCE, Status.BAD_GUESS]


def test_unknown_option_is_rejected(reference, points):
    xs, ys = points
    z = np.zeros(xs.shape[0])
    st = np.zeros(xs.shape[0], dtype=np.int8)
    with pytest.raises(ValueError, match="max_moves"):
        surface_fit.refine(reference, reference, xs, ys, z, z, st, HALF, spacing=0.2)
