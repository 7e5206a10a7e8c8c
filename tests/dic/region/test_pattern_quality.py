"""Pattern quality (``dic.region.pattern_quality``): MIG, clipping, speckle size and focus on images with known answers."""

import math

import numpy as np
import pytest

from livedic.dic.region.pattern_quality import FOCUS_SPREAD, pattern_quality
from tests.conftest import blurred_noise


def gaussian_dots(shape=(300, 300), fwhm=4.0, count=1500, seed=0):
    """Random Gaussian spots of a known FWHM (not the simulator's renderer), 8-bit, dark on light."""
    rng = np.random.default_rng(seed)
    rows, cols = np.indices(shape, dtype=np.float64)
    sigma = fwhm / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    image = np.zeros(shape)
    for y, x in rng.uniform(0, shape, size=(count, 2)):
        y0, y1, x0, x1 = int(max(y - 4 * sigma, 0)), int(min(y + 4 * sigma + 1, shape[0])), \
            int(max(x - 4 * sigma, 0)), int(min(x + 4 * sigma + 1, shape[1]))
        image[y0:y1, x0:x1] += np.exp(-((rows[y0:y1, x0:x1] - y) ** 2 + (cols[y0:y1, x0:x1] - x) ** 2) /
                                      (2 * sigma * sigma))
    return np.clip(220 - 160 * image, 0, 255).round().astype(np.uint8)


def test_the_mig_of_a_ramp_is_its_slope():
    ramp = np.tile(np.arange(200, dtype=np.float64) * 0.75, (120, 1))
    quality = pattern_quality(ramp, 21)
    assert quality.mig[60, 100] == pytest.approx(0.75, rel=1e-5)
    assert quality.noise_per_grey_level() == pytest.approx(math.sqrt(2) / (21 * quality.mig_median))


def test_clipped_pixels_are_counted_at_the_bit_depth():
    image = np.full((100, 100), 2000, np.uint16)
    image[:10] = 4095                               # a 12-bit camera's saturation in 16-bit frames
    assert pattern_quality(image, 11, bit_depth=12).clipped_share == pytest.approx(0.1)
    assert pattern_quality(image, 11).clipped_share == 0.0
    assert "clipped" in " ".join(pattern_quality(image, 11, bit_depth=12).advice())


@pytest.mark.parametrize("fwhm", [3.0, 5.0, 8.0])
def test_the_speckle_size_is_the_speckles_fwhm(fwhm):
    quality = pattern_quality(gaussian_dots(fwhm=fwhm, count=int(9e4 / fwhm ** 2)), 21)
    assert quality.speckle_px == pytest.approx(fwhm, rel=0.15)


def test_large_speckles_for_the_subset_are_advised_against():
    advice = pattern_quality(gaussian_dots(fwhm=10.0, count=900), 21).advice()
    assert any("large for a 21 px subset" in line and "--subset 31" in line for line in advice)


def test_an_evenly_sharp_pattern_needs_no_advice_and_half_of_it_blurred_does():
    import cv2
    image = blurred_noise((320, 320), seed=4, sigma=1.2)
    image = np.clip(30 + (image - image.min()) / np.ptp(image) * 190, 0, 255).astype(np.uint8)
    sharp = pattern_quality(image, 21)
    assert sharp.sharpness_spread < FOCUS_SPREAD and sharp.advice() == []
    blurred = image.copy()
    blurred[:, 160:] = cv2.GaussianBlur(image, (0, 0), 1.0)[:, 160:]
    quality = pattern_quality(blurred, 21)
    assert quality.sharpness_spread > FOCUS_SPREAD
    assert any("out of focus" in line for line in quality.advice())


def test_weak_subsets_are_those_with_little_contrast():
    image = blurred_noise((200, 200), seed=1, sigma=1.5)
    image = np.clip(30 + (image - image.min()) / np.ptp(image) * 190, 0, 255).astype(np.uint8)
    image[:, 100:] = 128                            # no texture on the right half
    quality = pattern_quality(image, 21, region=np.ones(image.shape, dtype=bool))
    weak = quality.weak_subsets(np.array([[50.0, 100.0], [160.0, 100.0]]))
    assert list(weak) == [False, True]
