"""dic.image_filter: the Gaussian pre-filter on analytic images, its one textual form, and its use by measure and
the trackers (a known translation still measured right; one filter per frame, shared by every entry point)."""

import math

import numpy as np
import pytest

from livedic.dic import Tracker, measure
from livedic.dic.image_filter import MAX_SIGMA, Prefilter
from livedic.dic.speckle import SpecklePattern, render
from livedic.dic.tracking.key_frames import KeyFrameTracker

SIGMAS = (0.4, 0.6, 0.8, 1.5, MAX_SIGMA)


@pytest.mark.parametrize("sigma", SIGMAS)
def test_a_linear_ramp_is_unchanged_away_from_the_border(sigma):
    """A normalised symmetric kernel keeps a plane exactly; only the mirrored border may differ."""
    y, x = np.mgrid[0:60, 0:70]
    ramp = (1.7 * x + 0.3 * y + 5.0).astype(np.float32)
    filtered = Prefilter(sigma).apply(ramp)
    reach = Prefilter(sigma).half_width
    assert filtered.dtype == np.float32 and filtered.shape == ramp.shape
    inner = (slice(reach, -reach), slice(reach, -reach))
    np.testing.assert_allclose(filtered[inner], ramp[inner], rtol=0, atol=2e-4)   # float32 of values < 130
    assert not np.allclose(filtered[:, 0], ramp[:, 0], atol=0.01)                 # the mirror does bend it


@pytest.mark.parametrize("dtype, scale", [(np.uint8, 1), (np.uint16, 200), (np.float64, 1.5), (np.int32, 7)])
def test_integer_and_float_frames_give_float32_not_rounded(dtype, scale):
    frame = (np.random.default_rng(3).integers(0, 256, (40, 50)) * scale).astype(dtype)
    filtered = Prefilter(0.6).apply(frame)
    assert filtered.dtype == np.float32 and filtered.flags.c_contiguous
    expected = Prefilter(0.6).apply(frame.astype(np.float32))
    np.testing.assert_allclose(filtered, expected, rtol=1e-6, atol=1e-6 * scale * 255)
    assert not np.array_equal(filtered, np.round(filtered))       # not rounded back to integers


def _sampled_gaussian_sd(sigma, half):
    k = np.arange(-half, half + 1, dtype=np.float64)
    w = np.exp(-k * k / (2 * sigma * sigma))
    return math.sqrt(float((w * k * k).sum() / w.sum()))


@pytest.mark.parametrize("sigma", SIGMAS)
def test_a_delta_spreads_into_a_separable_gaussian_of_unit_sum_and_the_right_sd(sigma):
    size = 41
    delta = np.zeros((size, size), np.float32)
    delta[20, 20] = 1.0
    response = Prefilter(sigma).apply(delta).astype(np.float64)
    assert response.sum() == pytest.approx(1.0, abs=1e-6)
    np.testing.assert_allclose(response, response.T, atol=1e-7)          # the same along x and y
    np.testing.assert_allclose(response, response[::-1, ::-1], atol=1e-7)  # centred
    column = response.sum(axis=0)
    np.testing.assert_allclose(response, np.outer(column, column), atol=1e-7)   # separable
    offsets = np.arange(size) - 20
    sd = math.sqrt(float((column * offsets ** 2).sum()))
    # the sampled, truncated Gaussian's own SD (narrower than sigma below ~0.7 px: few samples) ...
    assert sd == pytest.approx(_sampled_gaussian_sd(sigma, Prefilter(sigma).half_width), rel=1e-5)
    if sigma >= 1.0:                      # ... which is sigma itself once the kernel samples it well
        assert sd == pytest.approx(sigma, rel=0.01)


def test_none_returns_the_frame_as_it_is():
    frame = np.arange(64, dtype=np.uint16).reshape(8, 8)
    assert Prefilter.parse("none").apply(frame) is frame and not Prefilter().active


@pytest.mark.parametrize("text, canonical", [("none", "none"), ("NONE", "none"), ("gaussian:0.60", "gaussian:0.6"),
                                             ("Gaussian:2", "gaussian:2"), (" gaussian:0.4 ", "gaussian:0.4")])
def test_the_text_round_trips_to_its_canonical_form(text, canonical):
    parsed = Prefilter.parse(text)
    assert str(parsed) == canonical and Prefilter.parse(str(parsed)) == parsed


@pytest.mark.parametrize("text", ["gaussian:0", "gaussian:-0.5", "gaussian:2.01", "gaussian:nan", "gaussian:inf",
                                  "gaussian:x", "gaussian", "gaussian:", "median:3", "box", ""])
def test_a_bad_value_is_one_line_naming_the_accepted_forms(text):
    with pytest.raises(ValueError) as error:
        Prefilter.parse(text)
    message = str(error.value)
    assert "\n" not in message and repr(text) in message and "gaussian:SIGMA" in message


SHIFT = (0.3, -0.6)


@pytest.fixture(scope="module")
def pair():
    """Exact (unquantised) images: with 8-bit rounding one point's error here is 0.025 px with or without a filter."""
    pattern = SpecklePattern((160, 160), n_speckles=390, radius=4.0, seed=7)
    return tuple(200.0 * render(pattern, shift, bit_depth=None) for shift in (None, SHIFT))


@pytest.fixture(scope="module")
def points():
    return np.array([(x, y) for y in range(40, 121, 20) for x in range(40, 121, 20)], dtype=float)


@pytest.mark.parametrize("prefilter", ["gaussian:0.4", "gaussian:0.8", "gaussian:2"])
def test_measure_with_the_prefilter_still_finds_a_known_translation(pair, points, prefilter):
    result = measure(*pair, points, subpixel="icgn", prefilter=prefilter)
    assert result.ok.all()
    error = np.hypot(result.u - SHIFT[0], result.v - SHIFT[1])
    assert np.sqrt(np.mean(error ** 2)) < 0.001 and error.max() < 0.003     # test_measure's IC-GN bounds
    # both images were filtered, once: a filter on one image only would still find a symmetric blur's shift
    filtering = Prefilter.parse(prefilter)
    by_hand = measure(filtering.apply(pair[0]), filtering.apply(pair[1]), points, subpixel="icgn")
    np.testing.assert_array_equal(result.u, by_hand.u)
    np.testing.assert_array_equal(result.v, by_hand.v)


def test_the_trackers_filter_each_frame_once_as_measure_does(pair, points):
    """The key-frame tracker, the plain tracker and measure see the same filtered images: the same numbers."""
    reference, deformed = pair
    filtering = Prefilter.parse("gaussian:0.6")
    plain = Tracker(reference, points, prefilter=filtering).track(deformed)
    keyed = KeyFrameTracker(reference, points, prefilter="gaussian:0.6", reference_update="never").track(deformed)
    by_hand = Tracker(filtering.apply(reference), points).track(filtering.apply(deformed))
    for name in ("u", "v", "zncc", "status"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(by_hand, name))
        np.testing.assert_array_equal(getattr(keyed, name), getattr(by_hand, name))
    unfiltered = Tracker(reference, points).track(deformed)
    assert not np.array_equal(plain.u, unfiltered.u)          # the filter was applied, not ignored
    assert np.hypot(plain.u - SHIFT[0], plain.v - SHIFT[1]).max() < 0.003
