import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from livedic.dic import Status, zncc
from tests.conftest import blurred_noise


def _numpy_zncc(f, g):
    f = f - f.mean()
    g = g - g.mean()
    return float((f * g).sum() / np.sqrt((f * f).sum() * (g * g).sum()))


def test_identical_subsets_correlate_perfectly():
    image = blurred_noise((64, 64))
    c, status = zncc(image, image, [(20, 30), (40, 41)], [(0, 0), (0, 0)], subset=11)
    assert np.all(status == Status.OK)
    np.testing.assert_allclose(c, 1.0, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(gain=st.floats(0.05, 20.0), offset=st.floats(-500.0, 500.0), seed=st.integers(0, 1000))
def test_invariant_under_affine_intensity_change(gain, offset, seed):
    f = blurred_noise((48, 48), seed=seed).astype(np.float64)
    g = np.roll(blurred_noise((48, 48), seed=seed + 1), 1, axis=0).astype(np.float64)
    points = [(24, 24), (15, 30)]
    shifts = [(1, -2), (0, 3)]
    c1, _ = zncc(f, g, points, shifts, subset=15)
    c2, _ = zncc(f, gain * g + offset, points, shifts, subset=15)
    np.testing.assert_allclose(c1, c2, atol=1e-5)


def test_matches_numpy_definition(rng):
    f = blurred_noise((50, 60), seed=3)
    g = blurred_noise((50, 60), seed=4)
    points = [(30, 25), (12, 12)]
    shifts = [(2, -1), (-3, 4)]
    c, status = zncc(f, g, points, shifts, subset=9)
    for (x, y), (u, v), value in zip(points, shifts, c):
        fs = f[y - 4:y + 5, x - 4:x + 5].astype(np.float64)
        gs = g[y + v - 4:y + v + 5, x + u - 4:x + u + 5].astype(np.float64)
        assert value == pytest.approx(_numpy_zncc(fs, gs), abs=1e-6)


def test_flat_and_outside_subsets_are_flagged_not_numbers():
    image = blurred_noise((40, 40))
    image[:, :15] = 100.0                      # flat strip on the left
    points = [(7, 20), (2, 20), (30, 20), (30, 20)]
    shifts = [(0, 0), (0, 0), (20, 0), (0, 0)]
    deformed = image.copy()
    deformed[10:30, 22:38] = 50.0              # flat where the last point lands
    c, status = zncc(image, deformed, points, shifts, subset=9)
    assert list(status) == [Status.FLAT_REFERENCE, Status.OUTSIDE_REFERENCE, Status.OUTSIDE_TARGET, Status.FLAT_TARGET]
    assert np.all(np.isnan(c))


@pytest.mark.parametrize("kwargs, message", [
    (dict(subset=10), "odd"),
    (dict(subset=101), "larger than the image"),
])
def test_bad_subset_is_a_clear_error(kwargs, message):
    image = blurred_noise((40, 40))
    with pytest.raises(ValueError, match=message):
        zncc(image, image, [(20, 20)], [(0, 0)], **kwargs)


def test_mismatched_sizes_are_a_clear_error():
    with pytest.raises(ValueError, match="same size"):
        zncc(blurred_noise((40, 40)), blurred_noise((40, 41)), [(20, 20)], [(0, 0)])


def test_reference_status_is_the_zncc_of_the_reference_with_itself(rng):
    """The tracker's reference check (no ZNCC computed) gives _zncc_batch's status bit for bit: at the edges, on
    flat patches, on nearly flat ones (grey levels a rounding step apart) and on texture."""
    from livedic.dic.correlation import _reference_status_batch, _zncc_batch
    image = blurred_noise((96, 96), seed=3).astype(np.float64)
    image[10:40, 10:40] = 7.0                       # flat
    image[50:80, 10:40] = 1000.0 + 1e-4 * rng.standard_normal((30, 30))   # flat within the tolerance
    image[50:80, 50:80] = 3.0 + (rng.random((30, 30)) < 0.002)             # a speck or two on a flat patch
    half = 5
    ys, xs = np.mgrid[0:96:3, 0:96:3]
    xs, ys = xs.ravel().astype(np.int64), ys.ravel().astype(np.int64)
    zero = np.zeros(xs.size, dtype=np.int64)
    expected = np.empty(xs.size, dtype=np.int8)
    _zncc_batch(image, image, xs, ys, zero, zero, half, np.empty(xs.size), expected)
    status = np.empty(xs.size, dtype=np.int8)
    _reference_status_batch(image, xs, ys, half, status)
    np.testing.assert_array_equal(status, expected)
    assert {Status.OK, Status.OUTSIDE_REFERENCE, Status.FLAT_REFERENCE} <= set(status.tolist())
