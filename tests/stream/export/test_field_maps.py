"""Tests of stream/export/field_maps.py: the surface mesh, the pixels of its triangles, the overlay and picture."""

import cv2
import numpy as np
import pytest
from matplotlib import colormaps

from livedic.stream.export.field_maps import (LONG_EDGE, MIN_PANEL_HEIGHT, MapLayout, PixelWeights, SurfaceMesh,
                                              _twice_area, encode_png, overlay)
from livedic.stream.export.field_options import quantities

STEP = 10.0


def _grid(nx=5, ny=4, x0=20.0, y0=30.0):
    x, y = np.meshgrid(x0 + STEP * np.arange(nx), y0 + STEP * np.arange(ny))
    return x.ravel(), y.ravel()


def test_a_grid_is_covered_by_two_triangles_a_cell_with_no_long_edge():
    x, y = _grid()
    mesh = SurfaceMesh.over(x, y, STEP)
    assert len(mesh.triangles) == 2 * 4 * 3
    assert np.abs(_twice_area(x, y, mesh.triangles)).sum() == pytest.approx(2 * 40 * 30)


def test_a_gap_in_the_grid_is_not_bridged():
    x, y = _grid(nx=6)
    keep = ~np.isin(np.round(x), [50.0, 60.0])         # two missing columns: a 30 px gap
    mesh = SurfaceMesh.over(x[keep], y[keep], STEP)
    corners = np.stack([x[keep][mesh.triangles], y[keep][mesh.triangles]], axis=-1)
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=-1)
    assert edges.max() <= LONG_EDGE * STEP and len(mesh.triangles) == 2 * 2 * 3     # column 70 alone: none


@pytest.mark.parametrize("x, y", [([1.0, 2.0], [1.0, 2.0]), ([0.0, 10.0, 20.0], [0.0, 0.0, 0.0])])
def test_too_few_or_collinear_points_give_no_triangles(x, y):
    mesh = SurfaceMesh.over(np.array(x), np.array(y), STEP)
    assert mesh.triangles.shape == (0, 3)


def test_where_keeps_the_triangles_with_three_valid_corners():
    x, y = _grid(nx=3, ny=3)
    mesh = SurfaceMesh.over(x, y, STEP)
    assert len(mesh.triangles) == 8 and np.array_equal(mesh.where(np.ones(9, dtype=bool)), mesh.triangles)
    for lost in range(9):
        valid = np.arange(9) != lost
        kept = mesh.where(valid)
        assert not (kept == lost).any() and len(kept) == 8 - int((mesh.triangles == lost).any(axis=1).sum())
    assert mesh.where(np.zeros(9, dtype=bool)).shape == (0, 3)


def test_pixel_weights_reproduce_a_linear_field_exactly_and_nan_outside():
    x, y = _grid()
    mesh = SurfaceMesh.over(x, y, STEP)
    moved_x, moved_y = x + 0.3 + 0.02 * (x - 40), y - 0.7      # an affine motion keeps the triangles' orientation
    weights = PixelWeights((100, 120), moved_x, moved_y, mesh.triangles, _twice_area(x, y, mesh.triangles))
    field = weights.sample(2.0 * moved_x - 3.0 * moved_y + 5.0)
    rows, cols = np.nonzero(np.isfinite(field))
    assert np.allclose(field[rows, cols], 2.0 * cols - 3.0 * rows + 5.0, atol=1e-9)
    assert cols.min() >= np.floor(moved_x.min()) and cols.max() <= np.ceil(moved_x.max())
    assert rows.min() >= np.floor(moved_y.min()) and rows.max() <= np.ceil(moved_y.max())
    assert np.isnan(field[:20]).all() and np.isnan(field[:, :20]).all()
    assert len(rows) == pytest.approx(40 * 1.02 * 30, rel=0.1)
    assert np.isnan(weights.sample(np.where(np.arange(x.size) == 7, np.nan, 1.0))[rows, cols]).any()


def test_a_folded_triangle_is_left_out():
    x = np.array([0.0, 10.0, 0.0, 10.0]) + 20
    y = np.array([0.0, 0.0, 10.0, 10.0]) + 20
    triangles = np.array([[0, 1, 2], [1, 3, 2]])
    reference = _twice_area(x, y, triangles)
    folded_x = x.copy()
    folded_x[3] = x[0] - 5                                   # point 3 jumped across: its triangle flips
    weights = PixelWeights((60, 60), folded_x, y, triangles, reference)
    assert set(map(tuple, np.unique(weights.corners, axis=0))) == {(0, 1, 2)}


def test_overlay_paints_the_colour_map_and_keeps_the_camera_image_elsewhere():
    gray = np.full((4, 5), 90, dtype=np.uint8)
    values = np.full((4, 5), np.nan)
    values[1, 1], values[2, 3] = 0.0, 1.0
    opaque = overlay(gray, values, (0.0, 1.0))
    lut = colormaps["turbo"](np.arange(256), bytes=True)[:, 2::-1]
    assert np.array_equal(opaque[1, 1], lut[0]) and np.array_equal(opaque[2, 3], lut[255])
    assert (opaque[np.isnan(values)] == 90).all()
    half = overlay(gray, values, (0.0, 1.0), opacity=0.5)
    assert np.array_equal(half[1, 1], np.round(0.5 * lut[0].astype(float) + 45).astype(np.uint8))


def test_the_picture_is_even_sized_with_the_image_at_the_bottom_left():
    image = np.random.default_rng(0).integers(0, 255, (101, 77), dtype=np.uint8)
    layout = MapLayout(image.shape, title_note="test.mcap")
    coloured = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    shown = quantities()
    picture = layout.picture(coloured, shown["eyy"], (0.0, 5.0), 3, 0.25)
    assert picture.shape[0] % 2 == 0 and picture.shape[1] % 2 == 0
    assert layout.panel_height == MIN_PANEL_HEIGHT and picture.shape[0] >= MIN_PANEL_HEIGHT
    assert np.array_equal(picture[picture.shape[0] - 101:, :77], coloured)
    assert picture.shape[1] > 77                                 # the colour bar beside it
    decoded = cv2.imdecode(np.frombuffer(encode_png(picture), np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(decoded, picture)
