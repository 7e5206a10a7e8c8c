"""Tests of dic/region/specimen.py: the speckled specimen found by its texture, and the texture measure itself."""

import numpy as np
import pytest

from livedic.dic.region import Specimen, find_specimen, placeable, speckle_texture
from livedic.dic.region.specimen import _otsu
from tests.conftest import blurred_noise, specimen_scene


def test_the_specimen_is_found_on_its_background_to_a_pixel_or_two():
    image, truth = specimen_scene(noise=3.0)
    found = find_specimen(image, 21)
    assert found.separated
    wrong = found.mask ^ truth
    assert wrong.sum() <= 4 * truth.shape[0]          # at most ~2 px along each of the two long edges
    assert not (found.mask & ~truth)[:, :95].any() and not (found.mask & ~truth)[:, 205:].any()
    assert found.bounds[0] in range(98, 103) and found.bounds[2] in range(96, 103)


def test_a_hole_is_left_out_and_no_subset_reaches_into_it():
    hole = (150, 200, 25)
    image, truth = specimen_scene(hole=hole, seed=3)
    found = find_specimen(image, 21)
    allowed = placeable(found.mask, 21, 2)
    rows, cols = np.nonzero(allowed)
    # the nearest allowed centre keeps a subset's half-diagonal plus the margin from the hole
    nearest = np.sqrt((cols - hole[0]) ** 2 + (rows - hole[1]) ** 2).min()
    assert nearest >= hole[2] + 10
    assert found.mask[hole[1], hole[0]] == False  # noqa: E712


def test_the_same_scene_at_16_bits_gives_the_same_specimen():
    image8, _ = specimen_scene(seed=5)
    image16 = image8.astype(np.uint16) * 257
    assert np.array_equal(find_specimen(image8, 21).mask, find_specimen(image16, 21).mask)


def test_an_image_speckled_throughout_is_all_specimen_but_its_flat_and_saturated_spots():
    image = blurred_noise((300, 300), seed=2, sigma=1.5)
    image = np.clip(40 + (image - image.min()) / np.ptp(image) * 180, 0, 255).astype(np.uint8)
    image[100:160, 100:160] = 255                        # glare: saturated, no texture
    found = find_specimen(image, 21)
    assert not found.separated or found.mask.mean() > 0.9
    assert not found.mask[110:150, 110:150].any()
    assert found.mask[:80, :80].all() and found.mask[200:, 200:].all()


def test_a_blank_image_has_no_specimen():
    found = find_specimen(np.full((64, 64), 90, np.uint8), 21)
    assert not found.mask.any() and found.bounds is None
    assert "no speckled area" in found.describe()


def test_texture_is_zero_on_a_flat_area_and_along_a_straight_edge_or_ramp():
    rows, cols = np.indices((60, 80), dtype=np.float32)
    assert np.all(speckle_texture(np.full((60, 80), 90.0)) == 0)
    ramp = 2.0 * cols + 0.5 * rows                    # gradient in one direction only: rank-one tensor
    inside = (slice(5, -5), slice(5, -5))             # a window reaching the image's border sees a bend there
    assert np.max(speckle_texture(ramp)[inside]) < 1e-6
    edge = np.where(cols < 40, 50.0, 200.0)
    assert np.max(speckle_texture(edge)[inside]) < 1e-3


def test_texture_of_a_pattern_in_both_directions_is_its_smaller_gradient_energy():
    # I = a sin(kx) + b sin(ky): the box-averaged structure tensor is ~diag(a^2 k^2 / 2, b^2 k^2 / 2)
    rows, cols = np.indices((90, 90), dtype=np.float64)
    k, a, b = 2 * np.pi / 9.0, 40.0, 20.0              # period = the 9 px window: exact averages
    image = a * np.sin(k * cols) + b * np.sin(k * rows)
    texture = speckle_texture(image)[20:70, 20:70]
    central = np.sin(k) ** 2 / k ** 2               # the central difference's gain on k, squared
    assert np.allclose(texture, 0.5 * b ** 2 * k ** 2 * central, rtol=1e-3)


def test_otsu_splits_two_populations_between_them():
    low = np.random.default_rng(0).normal(-2, 0.2, 500)
    high = np.random.default_rng(1).normal(1, 0.3, 300)
    values = np.concatenate([low, high])
    split = _otsu(values)
    half_bin = 0.5 * np.ptp(values) / 256              # the split is a histogram bin's centre
    assert low.max() - half_bin <= split < high.min()


def test_a_specimen_in_two_pieces_says_so():
    image, _ = specimen_scene(seed=4)
    image = image.copy()
    image[190:210, :] = 120                           # a flat band cuts the strip in two
    found = find_specimen(image, 21)
    assert found.pieces == 2 and found.separated
    assert not found.mask[195:205, :].any()
    assert "in 2 pieces" in found.describe() and found.share == pytest.approx(found.mask.mean())


def test_pieces_too_small_for_a_few_subsets_are_dropped():
    image, truth = specimen_scene(seed=6)
    image = image.copy()
    patch = np.clip(40 + blurred_noise((30, 30), seed=9, sigma=1.5) * 0.7, 0, 255).astype(np.uint8)
    image[20:50, 240:270] = patch                     # a 30 px speckled patch on the background: < 4 subsets
    found = find_specimen(image, 21)
    assert found.pieces == 1 and not found.mask[:, 220:].any()


def test_a_specimen_record_reports_its_bounds():
    mask = np.zeros((20, 30), dtype=bool)
    mask[5:8, 10:20] = True
    specimen = Specimen(mask, 1.0, True, 1, float(mask.mean()))
    assert specimen.bounds == (10, 5, 10, 3)
    assert specimen.describe().startswith("the speckled specimen: 5 % of the image, within 10,5,10,3")
