"""Band end fits of the virtual extensometer (``end_fit=BAND``): the points on a line across the specimen at each end.

Analytic fields: a rigid motion reads 0, a uniform stretch, a gradient across the width and a neck-like
curvature along the gauge are exact at the ends; on independent synthetic point noise the reading's scatter is
the one its fit weights predict, several times below the local fit's on a specimen-wide grid.
"""

import math

import numpy as np
import pytest

from livedic.dic.strain import field_fit
from livedic.dic.strain.extensometer import (BAND, LOCAL, Extensometer, ExtensometerOffPoints, place_extensometers,
                                             read_extensometers, strain_noise)

STEP = 14.0


def specimen(columns=29, rows=60, step=STEP, origin=(100.0, 60.0)):
    """A grid as livedic run places on the simulated test's gauge section (29 points across)."""
    xs, ys = np.meshgrid(origin[0] + step * np.arange(columns), origin[1] + step * np.arange(rows))
    return np.column_stack([xs.ravel(), ys.ravel()])


# Ends off the grid rows on purpose; an oblique one checks the band follows its own axis.
AXIAL = Extensometer("axial", 297.3, 150.6, 297.3, 550.6, BAND)
OBLIQUE = Extensometer("oblique", 250.2, 200.7, 330.9, 600.1, BAND)


def exact_strain(extensometer, displacement):
    (x1, y1), (x2, y2) = extensometer.ends
    u, v = displacement(np.array([x1, x2]), np.array([y1, y2]))
    return math.hypot(x2 + u[1] - x1 - u[0], y2 + v[1] - y1 - v[0]) / extensometer.length_px - 1.0


def read(displacement, extensometers=(AXIAL, OBLIQUE), ok=None):
    points = specimen()
    placed = place_extensometers(extensometers, points, step=STEP)
    u, v = displacement(points[:, 0], points[:, 1])
    ok = np.ones(len(points), dtype=bool) if ok is None else ok
    return read_extensometers(placed, points, u, v, ok)


@pytest.mark.parametrize("angle", [0.0, 0.02, -0.3])
def test_a_rigid_motion_reads_zero(angle):
    c, s = math.cos(angle), math.sin(angle)

    def rigid(x, y):        # an exact rotation about (300, 400) and a translation
        dx, dy = x - 300.0, y - 400.0
        return c * dx - s * dy - dx + 2.6, s * dx + c * dy - dy - 1.4
    readings = read(rigid)
    assert readings.ok.all()
    np.testing.assert_allclose(readings.eng_strain, 0.0, atol=1e-13)


def test_a_uniform_stretch_is_exact():
    def stretch(x, y):
        return -0.3 * 0.05 * (x - 300.0) + 0.4, 0.05 * (y - 400.0) - 0.7
    readings = read(stretch)
    assert readings.eng_strain[0] == pytest.approx(0.05, abs=1e-13)
    assert readings.eng_strain[1] == pytest.approx(exact_strain(OBLIQUE, stretch), abs=1e-13)


def test_a_gradient_across_the_width_is_exact_not_averaged_into_elongation():
    # The axial strain grows linearly across the width (a bending load) and the specimen turns a little: the band's
    # linear terms across it read the strain on the extensometer's own line, as the local fit does.
    def gradient(x, y):
        return 0.01 * (y - 400.0), 0.03 * (y - 400.0) * (1.0 + 0.004 * (x - 300.0)) - 0.01 * (x - 300.0)
    readings = read(gradient, extensometers=(AXIAL,))
    assert readings.eng_strain[0] == pytest.approx(exact_strain(AXIAL, gradient), abs=1e-12)
    local = read(gradient, extensometers=(Extensometer("axial", *AXIAL.ends.ravel(), LOCAL),))
    assert local.eng_strain[0] == pytest.approx(readings.eng_strain[0], abs=1e-12)


def test_a_curvature_along_the_gauge_is_exact_at_the_ends():
    # Strain varying linearly along the gauge (a neck's flank): v quadratic in y; the band is quadratic along it
    # (not across: a curvature across the width is not modelled, the local fit's t^2 term is left out).
    def flank(x, y):
        return -1e-5 * (x - 300.0) * (y - 400.0), 0.02 * (y - 400.0) + 4e-5 * (y - 400.0) ** 2
    readings = read(flank, extensometers=(AXIAL,))
    assert readings.eng_strain[0] == pytest.approx(exact_strain(AXIAL, flank), abs=1e-12)


def test_noise_falls_by_the_fit_weights_ratio():
    # Independent point noise: the band's scatter is what its weights predict (strain_noise), and on 29 points
    # across it is about 3.7 x below the local fit's (the band holds ~7 rows x 29 points, the disk ~20 points).
    points = specimen()
    local = Extensometer("local", *AXIAL.ends.ravel(), LOCAL)
    placed = place_extensometers([AXIAL, local], points, step=STEP)
    predicted = strain_noise(placed, points, 0.01)
    rng = np.random.default_rng(7)
    trials = np.array([read_extensometers(placed, points, rng.normal(0, 0.01, len(points)),
                                          rng.normal(0, 0.01, len(points)), np.ones(len(points), bool)).eng_strain
                       for _ in range(2000)])
    scatter = trials.std(axis=0)
    np.testing.assert_allclose(scatter, predicted, rtol=0.08)        # 2000 trials: the SD within ~3 %
    assert predicted[1] / predicted[0] > 3.0


def test_band_neighbourhoods_hold_the_rows_within_the_half_height_at_any_distance_across():
    points = specimen()
    start, index = field_fit.band_neighbourhoods(np.array([[297.3, 150.6]]), np.array([[0.0, 1.0]]), points, STEP)
    held = points[index[start[0]:start[1]]]
    assert np.all(np.abs(held[:, 1] - 150.6) <= field_fit.BAND_HALF_HEIGHT * STEP)
    assert len(np.unique(held[:, 0])) == 29                          # the whole width
    rows = np.unique(points[:, 1])
    assert len(np.unique(held[:, 1])) == np.count_nonzero(np.abs(rows - 150.6) <= field_fit.BAND_HALF_HEIGHT * STEP)


def test_a_band_end_beyond_the_rows_is_refused_not_extrapolated():
    points = specimen()                                             # y 60..886
    with pytest.raises(ExtensometerOffPoints, match="outside the tracked points"):
        place_extensometers([Extensometer("long", 300.0, 100.0, 300.0, 900.0, BAND)], points, step=STEP)
    place_extensometers([Extensometer("edge", 300.0, 60.0, 300.0, 886.0, BAND)], points, step=STEP)   # outermost rows
    with pytest.raises(ValueError, match="end fit 'disk' is not one of local, band"):
        place_extensometers([Extensometer("odd", 300.0, 100.0, 300.0, 500.0, "disk")], points, step=STEP)


def test_a_band_end_is_interpolated_across_its_line_never_extrapolated():
    points = specimen()                                             # columns x = 100, 114, ..., 296, 310, ..., 492
    band_rows = np.abs(points[:, 1] - 150.6) <= 4 * STEP
    stretch = lambda x, y: (0.0 * x, 0.01 * (y - 400.0))            # noqa: E731

    def reading(lost):
        ok = np.ones(len(points), dtype=bool)
        ok[band_rows & lost] = False
        return read(stretch, extensometers=(AXIAL,), ok=ok)
    # a crack from one edge up to the column next to the end (x 296, the end at 297.3): the rest pins it exactly
    kept = reading(points[:, 0] < 290.0)
    assert kept.ok[0] and kept.eng_strain[0] == pytest.approx(0.01, abs=1e-12)
    # one column further (the nearest valid point 0.9 step across the end): lost, not extrapolated
    for lost in (points[:, 0] < 300.0, points[:, 0] > 290.0, np.ones(len(points), dtype=bool)):
        gone = reading(lost)
        assert not gone.ok[0] and math.isnan(gone.eng_strain[0])


def test_a_band_end_whose_own_points_are_lost_is_lost_whatever_the_band_holds_across():
    # The points around the end gone (tracking failed there), the band's far points still ok: far points must not
    # carry the end (they may be ok and wrong), so it is lost as the local fit's end would be.
    points = specimen()
    ok = np.ones(len(points), dtype=bool)
    ok[np.hypot(points[:, 0] - 297.3, points[:, 1] - 150.6) < 3 * STEP] = False
    readings = read(lambda x, y: (0.0 * x, 0.01 * (y - 400.0)), extensometers=(AXIAL,), ok=ok)
    assert not readings.ok[0] and math.isnan(readings.eng_strain[0])
