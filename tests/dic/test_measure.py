"""dic.measure end to end: every search x sub-pixel method on exact simulated shifts, and bad input."""

import numpy as np
import pytest

from livedic.dic import SEARCH_METHODS, SUBPIXEL_METHODS, Status, measure
from livedic.dic.speckle import SpecklePattern, render

SHIFT = (3.3, -2.2)   # fractions well below 0.5: the integer ZNCC peak is the nearest pixel
# Bounds on the RMS and the largest |error| (px) per sub-pixel method on exact, unquantised images:
# without 8-bit quantisation noise (~0.003 px here) a small systematic bias cannot hide.
RMS_BOUND = {"none": 0.5, "surface-fit": 0.08, "gradient": 0.08, "newton-raphson": 0.001,
             "improved-surface-fit": 0.006, "icgn": 0.001, "icgn2": 0.001}
MAX_BOUND = {"none": 0.5, "surface-fit": 0.15, "gradient": 0.15, "newton-raphson": 0.003,
             "improved-surface-fit": 0.012, "icgn": 0.003, "icgn2": 0.003}


@pytest.fixture(scope="module")
def images():
    pattern = SpecklePattern((160, 160), n_speckles=390, radius=4.0, seed=7)
    return render(pattern, bit_depth=8), render(pattern, SHIFT, bit_depth=8)


@pytest.fixture(scope="module")
def exact_images():
    pattern = SpecklePattern((160, 160), n_speckles=390, radius=4.0, seed=7)
    return 200.0 * render(pattern, bit_depth=None), 200.0 * render(pattern, SHIFT, bit_depth=None)


@pytest.fixture(scope="module")
def points():
    axis = np.arange(40, 121, 20)
    xs, ys = np.meshgrid(axis, axis)
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(float)


@pytest.mark.parametrize("subpixel", SUBPIXEL_METHODS)
def test_every_subpixel_method_recovers_the_shift(exact_images, points, subpixel):
    reference, deformed = exact_images
    result = measure(reference, deformed, points, subpixel=subpixel, radius=6)
    assert result.ok.all(), Status(int(result.status[~result.ok][0])).description
    error = np.hypot(result.u - SHIFT[0], result.v - SHIFT[1])
    assert np.sqrt(np.mean(error ** 2)) <= RMS_BOUND[subpixel]
    assert np.max(error) <= MAX_BOUND[subpixel]
    assert np.all(result.zncc > 0.9)


@pytest.mark.parametrize("search", [s for s in SEARCH_METHODS if s != "none"])
def test_every_search_finds_the_integer_peak(images, points, search):
    # guided=False: every point is searched (guided, only a few seeds are; dic.reliability_guided)
    reference, deformed = images
    truth = measure(reference, deformed, points, search="exhaustive", subpixel="none", radius=6, guided=False)
    result = measure(reference, deformed, points, search=search, subpixel="none", radius=6, guided=False)
    assert result.ok.all()
    np.testing.assert_array_equal(truth.u, np.round(SHIFT[0]))
    np.testing.assert_array_equal(truth.v, np.round(SHIFT[1]))
    np.testing.assert_array_equal(result.u, truth.u)
    np.testing.assert_array_equal(result.v, truth.v)
    assert np.all(result.evaluations > 0)


# A rigid shift: the gradients are 0 up to the 8-bit rounding noise, which moves the 2nd-order fit's
# more (its slope at the centre shares the subset with three more terms per component).
@pytest.mark.parametrize("subpixel, bound", [("icgn", 5e-3), ("icgn2", 1e-2)])
def test_first_order_methods_report_gradients(images, points, subpixel, bound):
    reference, deformed = images
    result = measure(reference, deformed, points, subpixel=subpixel, radius=6)
    for gradient in (result.ux, result.uy, result.vx, result.vy):
        assert gradient is not None and np.max(np.abs(gradient)) < bound


def test_search_none_starts_from_the_guess(images, points):
    reference, deformed = images
    guess = np.array(SHIFT) + np.array([0.8, -0.7])
    result = measure(reference, deformed, points, search="none", subpixel="icgn", guess=guess)
    assert result.ok.all()
    assert np.max(np.abs(result.u - SHIFT[0])) < 0.02
    assert np.sqrt(np.mean((result.u - SHIFT[0]) ** 2)) < 0.005
    assert result.evaluations is None


def test_sixteen_bit_images_give_the_same_answer(points):
    pattern = SpecklePattern((160, 160), n_speckles=390, radius=4.0, seed=7)
    ref16, def16 = render(pattern, bit_depth=16), render(pattern, SHIFT, bit_depth=16)
    assert ref16.dtype == np.uint16
    result = measure(ref16, def16, points, subpixel="icgn", radius=6)
    assert result.ok.all()
    assert np.max(np.abs(result.u - SHIFT[0])) < 0.005


def test_same_seed_same_result(images, points):
    reference, deformed = images
    a = measure(reference, deformed, points, search="pso", subpixel="surface-fit", radius=8, seed=3)
    b = measure(reference, deformed, points, search="pso", subpixel="surface-fit", radius=8, seed=3)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.evaluations, b.evaluations)


def test_points_outside_and_nan_guess_are_flagged_not_crashes(images):
    reference, deformed = images
    points = [(80, 80), (3, 80), (80, 158), (80, 80)]
    guess = [SHIFT, SHIFT, SHIFT, (np.nan, 0.0)]
    for subpixel in SUBPIXEL_METHODS:
        result = measure(reference, deformed, points, subpixel=subpixel, guess=guess, radius=3)
        assert list(result.status) == [Status.OK, Status.OUTSIDE_REFERENCE, Status.OUTSIDE_REFERENCE,
                                       Status.BAD_GUESS], subpixel
        assert np.isnan(result.u[1:]).all() and np.isnan(result.v[1:]).all()


def test_flat_image_flags_every_point():
    flat = np.full((80, 80), 120, dtype=np.uint8)
    for subpixel in SUBPIXEL_METHODS:
        result = measure(flat, flat, [(40, 40), (30, 50)], subpixel=subpixel, radius=3)
        assert not result.ok.any()
        assert np.all(result.status == Status.FLAT_REFERENCE), subpixel


@pytest.mark.parametrize("change, message", [
    (dict(subset=22), "odd"),
    (dict(subset=401), "larger than the image"),
    (dict(search="simplex"), "unknown search method"),
    (dict(subpixel="magic"), "unknown sub-pixel method"),
    (dict(radius=-1), "radius"),
    (dict(guess=[(1.0, 2.0, 3.0)]), "guess"),
    (dict(interpolation="bspline4"), "choose one of bspline3, bspline5"),
    (dict(subpixel="icgn2", interpolation="bspline5"), "not available with --subpixel icgn2: use it with icgn"),
    (dict(interpolation="bspline5"), "not available with --subpixel improved-surface-fit"),
])
def test_bad_options_are_clear_errors(images, change, message):
    reference, deformed = images
    with pytest.raises(ValueError, match=message):
        measure(reference, deformed, [(80, 80)], **change)


def test_bad_images_are_clear_errors(images):
    reference, _ = images
    with pytest.raises(ValueError, match="same size"):
        measure(reference, reference[:, :-1], [(80, 80)])
    with pytest.raises(ValueError, match="2-D grey"):
        measure(np.dstack([reference] * 3), reference, [(80, 80)])
    with pytest.raises(ValueError, match="NaN"):
        measure(np.full((50, 50), np.nan), np.zeros((50, 50)), [(25, 25)])
    with pytest.raises(ValueError, match="points"):
        measure(reference, reference, [(np.nan, 3.0)])


def test_one_list_of_search_methods_and_the_front_door():
    """``dic.SEARCH_METHODS`` is ``dic.search``'s integer searches plus "none"; the package exports what users need."""
    from livedic import dic
    from livedic.dic import search
    assert dic.SEARCH_METHODS == search.SEARCH_METHODS + ("none",)
    for name in ("measure", "Measurement", "SEARCH_METHODS", "SUBPIXEL_METHODS", "Gates", "Status", "Tracker",
                 "grid_in_roi", "step_for_count", "zncc"):
        assert name in dic.__all__ and hasattr(dic, name), name


@pytest.mark.parametrize("guided", [True, False])
def test_quintic_interpolation_measures_the_shift_with_less_bias(exact_images, points, guided):
    """``interpolation="bspline5"`` (icgn): the guided propagation and the plain search + IC-GN both sample the
    quintic; on exact images its error is well below the cubic's."""
    reference, deformed = exact_images
    errors = {}
    for interpolation in ("bspline3", "bspline5"):
        m = measure(reference, deformed, points, subpixel="icgn", interpolation=interpolation, guided=guided,
                    guess=None if guided else (3.0, -2.0))
        assert m.ok.all()
        errors[interpolation] = np.sqrt(np.mean((m.u - SHIFT[0]) ** 2 + (m.v - SHIFT[1]) ** 2))
    assert errors["bspline5"] < errors["bspline3"] / 2
