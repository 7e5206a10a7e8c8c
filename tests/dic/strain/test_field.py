"""Strain fields by pointwise least squares (``dic.strain``) on analytic displacement fields.

Every expected value is worked out by hand from the field and the window; tolerances are stated
next to each check. Exact displacements go in, so the linear algebra alone sets the tolerance
(1e-12 on strains of order 1e-2..1).
"""

import math

import numpy as np
import pytest

from livedic.dic.strain import (MEASURES, StrainStatus, principal_strains,
                                strain_field, strain_tensor, strain_window, virtual_strain_gauge)

STEP = 10.0
SUBSET = 21


def grid(n=11, step=STEP, origin=(100.0, 200.0)):
    """(n*n, 2) points, row by row, every ``step`` px from ``origin``."""
    xs, ys = np.meshgrid(origin[0] + step * np.arange(n), origin[1] + step * np.arange(n))
    return np.column_stack([xs.ravel(), ys.ravel()])


def field_on(points, function):
    u, v = function(points[:, 0], points[:, 1])
    return np.asarray(u, dtype=float), np.asarray(v, dtype=float), np.ones(len(points), dtype=bool)


def interior(points, window, n=11, step=STEP, origin=(100.0, 200.0)):
    """Points whose full (window x window) block lies on the grid."""
    m = window // 2
    i = np.rint((points[:, 0] - origin[0]) / step)
    j = np.rint((points[:, 1] - origin[1]) / step)
    return (i >= m) & (i <= n - 1 - m) & (j >= m) & (j <= n - 1 - m)


# --------------------------------------------------------------------------- window and VSG

def test_vsg_is_window_minus_one_steps_plus_a_subset():
    assert virtual_strain_gauge(5, 10, 21) == 61.0          # (5 - 1) * 10 + 21
    assert virtual_strain_gauge(3, 7.5, 15) == 30.0
    windows = strain_window(grid(), window=7, subset=31)
    assert windows.step == pytest.approx(STEP)              # the grid's own spacing when not given
    assert windows.vsg_px == 6 * STEP + 31
    field = strain_field(windows, *field_on(grid(), lambda x, y: (0 * x, 0 * y)))
    assert field.vsg_px == 91.0


def test_window_must_be_odd_and_at_least_three():
    for bad in (1, 2, 4):
        with pytest.raises(ValueError, match="odd number of points >= 3"):
            strain_window(grid(), window=bad)
    with pytest.raises(ValueError, match="grid step"):
        strain_window(grid(), step=0.0)


def test_windows_are_the_square_blocks_and_shrink_at_the_border():
    points = grid(n=9)
    windows = strain_window(points, window=5)
    held = np.diff(windows.start)
    i = np.rint((points[:, 0] - 100.0) / STEP).astype(int)
    j = np.rint((points[:, 1] - 200.0) / STEP).astype(int)
    # Points a side: 5 inside, fewer within 2 points of an edge (3 at a corner).
    side = lambda k: np.minimum(k, 2) + np.minimum(8 - k, 2) + 1
    np.testing.assert_array_equal(held, side(i) * side(j))
    assert held.max() == 25 and held.min() == 9


# --------------------------------------------------------------------------- analytic fields

def test_uniform_strain_is_exact_everywhere_borders_included():
    points = grid()
    ux, uy, vx, vy = 0.012, -0.004, 0.007, -0.0035
    u, v, ok = field_on(points, lambda x, y: (0.3 + ux * (x - 150) + uy * (y - 250),
                                             -1.7 + vx * (x - 150) + vy * (y - 250)))
    for window in (3, 5, 9):
        field = strain_field(strain_window(points, window=window, subset=SUBSET), u, v, ok)
        # A 3-window's corner block holds 2 x 2 points, fewer than MIN_POINTS (6): no strain there.
        corners = np.isin(np.arange(len(points)), [0, 10, 110, 120]) if window == 3 else np.zeros(len(points), bool)
        assert np.all(field.status[corners] == StrainStatus.TOO_FEW_POINTS)
        assert np.all(field.status[~corners] == StrainStatus.OK)
        np.testing.assert_allclose(field.exx[~corners], ux, rtol=0, atol=1e-12)
        np.testing.assert_allclose(field.eyy[~corners], vy, rtol=0, atol=1e-12)
        np.testing.assert_allclose(field.exy[~corners], 0.5 * (uy + vx), rtol=0, atol=1e-12)
        for name, value in (("ux", ux), ("uy", uy), ("vx", vx), ("vy", vy)):
            np.testing.assert_allclose(getattr(field, name)[~corners], value, rtol=0, atol=1e-12)


def test_linear_strain_gradient_is_exact_at_interior_points():
    # u = a x^2 + b x y, v = c y^2 + d x y: strains vary linearly. Over a window symmetric about its
    # centre the even terms (dx^2, dx dy, dy^2) are orthogonal to dx and dy, so the plane's slopes
    # are the exact derivatives at the centre point.
    a, b, c, d = 2e-5, -1e-5, 3e-5, 1.5e-5
    points = grid(n=13)
    u, v, ok = field_on(points, lambda x, y: (a * x * x + b * x * y, c * y * y + d * x * y))
    x, y = points[:, 0], points[:, 1]
    for window in (3, 5, 7):
        field = strain_field(strain_window(points, window=window), u, v, ok)
        inside = interior(points, window, n=13)
        assert inside.sum() == (13 - 2 * (window // 2)) ** 2
        np.testing.assert_allclose(field.ux[inside], (2 * a * x + b * y)[inside], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(field.uy[inside], (b * x)[inside], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(field.vx[inside], (d * y)[inside], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(field.vy[inside], (2 * c * y + d * x)[inside], rtol=1e-12, atol=1e-13)


def test_border_window_gives_the_slope_at_its_centroid():
    # A border window is a rectangular block, symmetric about its own centroid: for a quadratic field
    # the plane is the exact derivative there, not at the point (the one-sided bias, stated).
    a = 2e-5
    points = grid(n=11)
    u, v, ok = field_on(points, lambda x, y: (a * x * x, 0 * y))
    windows = strain_window(points, window=5)
    field = strain_field(windows, u, v, ok)
    centroid_x = np.array([points[windows.index[windows.start[i]:windows.start[i + 1]], 0].mean()
                           for i in range(len(points))])
    np.testing.assert_allclose(field.ux, 2 * a * centroid_x, rtol=1e-12, atol=1e-13)
    edge = np.rint((points[:, 0] - 100.0) / STEP) == 0      # first column: block offsets 0, 1, 2 steps
    np.testing.assert_allclose(field.ux[edge] - 2 * a * points[edge, 0], 2 * a * STEP, rtol=1e-10)


def test_quadratic_strain_has_the_windows_known_bias():
    # u = k x^3: exact ux = 3 k x^2 (a quadratic strain field, exx'' = 6 k). Over offsets d = i h,
    # i = -m..m, the cubic term k d^3 adds cov(d^3, d) / var(d) = k h^2 sum(i^4) / sum(i^2) to the
    # slope: a bias of exx'' h^2 S / 6 with S = sum(i^4) / sum(i^2) (2: 1, 5: 3.4, 7: 7), the same
    # at every interior point.
    k = 1e-7
    points = grid(n=13)
    u, v, ok = field_on(points, lambda x, y: (k * x ** 3, 0 * y))
    x = points[:, 0]
    for window, s in ((3, 1.0), (5, 34.0 / 10.0), (7, 196.0 / 28.0)):
        assert s == pytest.approx(sum(i ** 4 for i in range(-(window // 2), window // 2 + 1))
                                  / sum(i ** 2 for i in range(-(window // 2), window // 2 + 1)))
        field = strain_field(strain_window(points, window=window), u, v, ok)
        inside = interior(points, window, n=13)
        bias = field.exx[inside] - 3 * k * x[inside] ** 2
        np.testing.assert_allclose(bias, 6 * k * STEP ** 2 * s / 6.0, rtol=1e-9)
        assert np.all(bias > 0)


def rotation(theta, centre=(150.0, 250.0)):
    c, s = math.cos(theta), math.sin(theta)

    def displacement(x, y):
        dx, dy = x - centre[0], y - centre[1]
        return (c - 1) * dx - s * dy, s * dx + (c - 1) * dy
    return displacement


def test_rigid_rotation_of_30_degrees_has_no_green_or_true_strain():
    points = grid()
    u, v, ok = field_on(points, rotation(math.radians(30.0)))
    windows = strain_window(points, window=5)
    for measure in ("green", "true"):
        field = strain_field(windows, u, v, ok, measure=measure)
        for name in ("exx", "eyy", "exy", "e1", "e2"):
            np.testing.assert_allclose(getattr(field, name), 0.0, rtol=0, atol=1e-12)
    # Small-strain theory sees cos(theta) - 1 = -0.134 along both axes and no shear.
    engineering = strain_field(windows, u, v, ok, measure="engineering")
    np.testing.assert_allclose(engineering.exx, math.cos(math.radians(30.0)) - 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(engineering.eyy, math.cos(math.radians(30.0)) - 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(engineering.exy, 0.0, rtol=0, atol=1e-12)


def stretch_and_rotation(l1, l2, phi, theta):
    """F = R(theta) U with U = R(phi) diag(l1, l2) R(phi)^T: displacement gradients (ux, uy, vx, vy)."""
    r = lambda a: np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    stretch = r(phi) @ np.diag([l1, l2]) @ r(phi).T
    f = r(theta) @ stretch
    return f[0, 0] - 1.0, f[0, 1], f[1, 0], f[1, 1] - 1.0, f


def test_hencky_strain_of_a_stretch_and_rotation_matches_numpys_eigen_decomposition():
    ux, uy, vx, vy, f = stretch_and_rotation(1.25, 0.9, math.radians(25.0), math.radians(40.0))
    points = grid()
    u, v, ok = field_on(points, lambda x, y: (ux * x + uy * y, vx * x + vy * y))
    field = strain_field(strain_window(points, window=5), u, v, ok, measure="true")
    w, vectors = np.linalg.eigh(f.T @ f)
    hencky = vectors @ np.diag(0.5 * np.log(w)) @ vectors.T
    np.testing.assert_allclose(field.exx, hencky[0, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(field.eyy, hencky[1, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(field.exy, hencky[0, 1], rtol=0, atol=1e-12)
    # ... which is ln U: principal values ln 1.25 and ln 0.9 along 25 degrees, whatever the rotation.
    np.testing.assert_allclose(field.e1, math.log(1.25), rtol=0, atol=1e-12)
    np.testing.assert_allclose(field.e2, math.log(0.9), rtol=0, atol=1e-12)
    np.testing.assert_allclose(field.angle, math.radians(25.0), rtol=0, atol=1e-12)
    # Not the component-wise log: ln(1 + ux) is a different number here.
    assert abs(field.exx[0] - math.log(1.0 + ux)) > 1e-3


def test_green_lagrange_is_half_of_ft_f_minus_identity():
    rng = np.random.default_rng(3)
    g = rng.uniform(-0.2, 0.2, size=(50, 4))
    exx, eyy, exy = strain_tensor(*g.T, measure="green")
    for row, e in zip(g, np.column_stack([exx, eyy, exy])):
        f = np.array([[1 + row[0], row[1]], [row[2], 1 + row[3]]])
        expected = 0.5 * (f.T @ f - np.eye(2))
        np.testing.assert_allclose(e, [expected[0, 0], expected[1, 1], expected[0, 1]], rtol=0, atol=1e-15)
    # engineering: the symmetric part of grad u
    exx, eyy, exy = strain_tensor(*g.T, measure="engineering")
    np.testing.assert_array_equal(exx, g[:, 0])
    np.testing.assert_array_equal(eyy, g[:, 3])
    np.testing.assert_allclose(exy, 0.5 * (g[:, 1] + g[:, 2]), rtol=0, atol=1e-17)
    with pytest.raises(ValueError, match="unknown strain measure"):
        strain_tensor(*g.T, measure="cauchy")
    with pytest.raises(ValueError, match="unknown strain measure"):
        strain_field(strain_window(grid()), *field_on(grid(), lambda x, y: (0 * x, 0 * y)), measure="log")
    assert MEASURES == ("engineering", "green", "true")


def test_principal_strains_and_angle_are_the_tensors_eigen_pairs():
    rng = np.random.default_rng(5)
    exx, eyy, exy = rng.uniform(-0.05, 0.05, size=(3, 200))
    e1, e2, angle = principal_strains(exx, eyy, exy)
    assert np.all(e1 >= e2)
    for k in range(200):
        tensor = np.array([[exx[k], exy[k]], [exy[k], eyy[k]]])
        w = np.linalg.eigvalsh(tensor)
        np.testing.assert_allclose([e2[k], e1[k]], w, rtol=0, atol=1e-15)
        direction = np.array([math.cos(angle[k]), math.sin(angle[k])])
        np.testing.assert_allclose(tensor @ direction, e1[k] * direction, rtol=0, atol=1e-15)
    # pure shear exy = 0.01: e1 = +0.01 at 45 degrees, e2 = -0.01
    e1, e2, angle = principal_strains(0.0, 0.0, 0.01)
    assert (float(e1), float(e2), float(angle)) == pytest.approx((0.01, -0.01, math.pi / 4), abs=1e-15)


# --------------------------------------------------------------------------- missing data

def linear(points):
    return field_on(points, lambda x, y: (0.01 * x, -0.02 * y))


def test_a_point_that_is_not_ok_gets_nan_and_its_own_status():
    points = grid()
    u, v, ok = linear(points)
    ok[60] = False
    u[61] = np.nan                                            # NaN displacement is not valid either
    field = strain_field(strain_window(points, window=5), u, v, ok)
    for i in (60, 61):
        assert field.status[i] == StrainStatus.POINT_NOT_OK
        assert all(np.isnan(getattr(field, name)[i]) for name in ("exx", "eyy", "exy", "e1", "e2", "angle", "ux"))
    # its neighbours still fit the plane over the remaining valid points: exact
    others = np.ones(len(points), dtype=bool)
    others[[60, 61]] = False
    assert np.all(field.status[others] == StrainStatus.OK)
    np.testing.assert_allclose(field.exx[others], 0.01, rtol=0, atol=1e-12)
    np.testing.assert_allclose(field.eyy[others], -0.02, rtol=0, atol=1e-12)
    assert StrainStatus.POINT_NOT_OK.description == "the point's displacement is not ok"


def test_too_few_valid_points_in_the_window_is_nan_never_zero():
    points = grid()
    u, v, ok = linear(points)
    windows = strain_window(points, window=5)
    centre = 60                                               # (5, 5) on the 11 x 11 grid: 25 points
    block = windows.index[windows.start[centre]:windows.start[centre + 1]]
    lost = [j for j in block if j != centre][:13]             # 12 of 25 left: below half
    ok[lost] = False
    field = strain_field(windows, u, v, ok)
    assert field.status[centre] == StrainStatus.TOO_FEW_POINTS
    assert np.isnan(field.exx[centre]) and np.isnan(field.eyy[centre]) and np.isnan(field.exy[centre])
    # one more valid point (13 of 25 >= half, >= 6) and the point has its exact strain back
    ok[lost[0]] = True
    again = strain_field(windows, u, v, ok)
    assert again.status[centre] == StrainStatus.OK
    assert again.exx[centre] == pytest.approx(0.01, abs=1e-12)


def test_valid_points_along_one_line_give_one_direction():
    # Points along a line (a row of points along a thin strip, or a diagonal): enough of them, but
    # no spread across the line, so no gradient across it can be fitted.
    for direction in ((1.0, 0.0), (math.sqrt(0.5), math.sqrt(0.5))):
        points = np.array([[100.0 + k * STEP * direction[0], 200.0 + k * STEP * direction[1]] for k in range(15)])
        u, v, ok = linear(points)
        field = strain_field(strain_window(points, window=7, step=STEP), u, v, ok)
        middle = slice(3, 12)                                  # 7 points in each window, all valid
        assert np.all(field.status[middle] == StrainStatus.ONE_DIRECTION), field.status
        assert np.all(np.isnan(field.exx[middle])) and np.all(np.isnan(field.exy[middle]))
    # On a grid: the two valid rows of a window span 1 step across (variance step^2 / 4, above the
    # MIN_SPREAD of 0.2 step^2): enough; one valid row and a single point off it are not.
    points = grid()
    u, v, ok = linear(points)
    j = np.rint((points[:, 1] - 200.0) / STEP)
    i = np.rint((points[:, 0] - 100.0) / STEP)
    ok[:] = (j == 4) | (j == 5)
    windows = strain_window(points, window=3)
    field = strain_field(windows, u, v, ok)
    inner = ok & (i > 0) & (i < 10)
    assert np.all(field.status[inner] == StrainStatus.OK)       # 6 of 9 valid, spread 0.25 step^2 >= 0.2
    np.testing.assert_allclose(field.eyy[inner], -0.02, rtol=0, atol=1e-12)
    ok[:] = (j == 5) | ((j == 4) & (i == 5))
    field = strain_field(windows, u, v, ok)
    centre = int(np.flatnonzero((i == 5) & (j == 5))[0])
    assert field.status[centre] == StrainStatus.TOO_FEW_POINTS  # 4 of 9
    assert StrainStatus.ONE_DIRECTION.description == "the valid points of the strain window lie along a line"


def test_a_p0_next_to_a_grid_point_joins_the_windows_without_biasing_a_linear_field():
    # livedic run puts P0 first and drops a grid point on the same pixel; a P0 one pixel off a grid
    # point stays as an extra point. The windows take it (half a step of slack in the reach) and the
    # plane through a linear field is still exact; an exact duplicate is harmless too.
    base = grid()
    for p0 in ((151.0, 250.0), (150.0, 250.0)):
        points = np.vstack([p0, base])
        u, v, ok = field_on(points, lambda x, y: (0.004 * x - 0.002 * y, 0.001 * x + 0.03 * y))
        windows = strain_window(points, window=5)
        assert windows.step == pytest.approx(STEP)
        field = strain_field(windows, u, v, ok)
        assert field.ok.all()
        np.testing.assert_allclose(field.exx, 0.004, rtol=0, atol=1e-12)
        np.testing.assert_allclose(field.eyy, 0.03, rtol=0, atol=1e-12)
        np.testing.assert_allclose(field.exy, -0.0005, rtol=0, atol=1e-12)
        held = np.diff(windows.start)
        assert held[0] == 26                               # P0's own block of 25 plus itself
        near = np.flatnonzero(np.all(np.abs(points[1:] - (150.0, 250.0)) <= 2 * STEP, axis=1)) + 1
        assert np.all(held[near] == 26)                   # the grid points whose block holds P0
