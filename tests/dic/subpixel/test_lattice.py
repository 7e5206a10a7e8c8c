"""Tests of dic/subpixel/lattice.py: lattice tables, footprints inside the image, and the node ZNCC kernel."""

import numpy as np
import pytest

from livedic.dic.speckle import render
from livedic.dic.subpixel.keys_cubic import keys_weights
from livedic.dic.subpixel.lattice import build_plane, lattice_tables, node_inside, node_zncc, valid_range
from tests.dic.subpixel.conftest import HALF, zncc_numpy


def test_lattice_kernel_matches_numpy_keys_interpolation(pattern, reference):
    deformed = render(pattern, (0.35, 0.6)).astype(np.float32)
    x, y, half = 120, 90, HALF
    side = 2 * half + 1
    f = reference[y - half:y + half + 1, x - half:x + half + 1].astype(np.float64)
    fhat = (f - f.mean()) / np.sqrt(np.sum((f - f.mean()) ** 2))
    ix, ph, lr, rr, wts = lattice_tables(0.2, 10)
    planes = np.empty((wts.shape[0], side + 7, side + 4), dtype=np.float32)
    org_x, org_y = x - half + ix[0], y - half + ix[0] - 1
    for p in range(wts.shape[0]):
        build_plane(deformed, planes, p, wts, org_x, org_y, float(deformed[y, x]))
    for i, j in [(0, 0), (2, 3), (-4, 1), (7, -6), (-10, 10)]:
        ki, kj = i + 10, j + 10
        c = node_zncc(fhat.astype(np.float32), planes, ph[ki], ix[ki] - ix[0], ix[kj] - ix[0], wts[ph[kj]], side)
        assert c == pytest.approx(zncc_numpy(reference, deformed, x, y, 0.2 * i, 0.2 * j), abs=1e-6)


def test_lattice_tables_split_offsets_into_integer_part_and_phase():
    ix, ph, lr, rr, wts = lattice_tables(0.2, 7)          # offsets -1.4 .. 1.4
    offsets = np.arange(-7, 8) * 0.2
    assert ix.tolist() == np.floor(offsets + 1e-9).astype(int).tolist()
    assert wts.shape == (5, 4) and ph.min() == 0 and ph.max() == 4
    assert ph[7] == 0 and ph[2] == 0 and ph[12] == 0        # offsets -1, 0, 1: phase 0
    np.testing.assert_array_equal(wts[0], [0.0, 1.0, 0.0, 0.0])
    for k in range(15):                                    # each phase's weights are Keys' at its fraction
        expected = np.empty(4)
        keys_weights(offsets[k] - ix[k], expected)
        if ph[k]:
            np.testing.assert_allclose(wts[ph[k]], expected, atol=1e-12)
    zero = ph == 0
    assert np.array_equal(lr, np.where(zero, ix, ix - 1)) and np.array_equal(rr, np.where(zero, ix, ix + 2))


def test_a_node_is_inside_when_its_whole_footprint_is():
    ix, ph, lr, rr, wts = lattice_tables(0.5, 4)           # offsets -2 .. 2
    size, half = 50, 5
    # footprint of index k at centre c: [c + lr[k] - half, c + rr[k] + half]
    for c in range(0, 50):
        for k in range(9):
            inside = c + lr[k] - half >= 0 and c + rr[k] + half <= size - 1
            assert node_inside(size, c, half, lr, rr, k) == inside


def test_the_valid_range_is_the_run_of_inside_nodes_around_the_middle():
    ix, ph, lr, rr, wts = lattice_tables(0.5, 4)
    size, half = 50, 5
    assert valid_range(size, 25, half, lr, rr, 0, 8, 4) == (0, 8)            # far from the edges: all
    lo, hi = valid_range(size, 7, half, lr, rr, 0, 8, 4)                     # near the left edge
    assert all(node_inside(size, 7, half, lr, rr, k) for k in range(lo, hi + 1))
    assert lo > 0 and not node_inside(size, 7, half, lr, rr, lo - 1) and hi == 8
    assert valid_range(size, 3, half, lr, rr, 0, 8, 4) == (1, 0)            # the middle itself outside


def test_a_flat_target_node_scores_minus_one(reference):
    side = 2 * HALF + 1
    flat = np.full((64, 64), 80.0, dtype=np.float32)
    f = reference[20:20 + side, 20:20 + side].astype(np.float64)
    fhat = ((f - f.mean()) / np.sqrt(np.sum((f - f.mean()) ** 2))).astype(np.float32)
    ix, ph, lr, rr, wts = lattice_tables(0.2, 5)
    planes = np.empty((wts.shape[0], side + 6, side + 2), dtype=np.float32)
    for p in range(wts.shape[0]):
        build_plane(flat, planes, p, wts, 20, 20, 80.0)
    assert node_zncc(fhat, planes, ph[7], ix[7] - ix[0], ix[6] - ix[0], wts[ph[6]], side) == -1.0
