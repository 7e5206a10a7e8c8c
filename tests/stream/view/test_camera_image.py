"""Tests of stream/view/camera_image.py: the camera image as 8-bit grey, downsampled by an integer, and paced."""

import numpy as np
import pytest

from livedic.stream.view.camera_image import IMAGE_SKIP_MAX, CameraImagePacing, display_gray, display_image, \
    display_scale


@pytest.mark.parametrize("pixel_format, full", [("Mono8", 255), ("Mono10", 1023), ("Mono12", 4095),
                                                ("Mono16", 65535), ("Unknown", 65535)])
def test_the_top_8_significant_bits_are_shown(pixel_format, full):
    dtype = np.uint8 if full == 255 else np.uint16
    image = np.array([[0, full // 2, full]], dtype=dtype)
    shown = display_gray(image, pixel_format)
    assert shown.dtype == np.uint8 and shown.tolist() == [[0, 127, 255]]
    if dtype == np.uint8:
        assert shown is image                                      # 8-bit images go as they are


def test_the_scale_is_the_smallest_integer_that_fits_the_larger_side():
    assert display_scale((480, 640), 640) == 1
    assert display_scale((480, 641), 640) == 2
    assert display_scale((2048, 1000), 512) == 4
    assert display_scale((2049, 1000, 3), 512) == 5
    for shape in [(100, 3000), (999, 7), (4096, 4096)]:
        scale = display_scale(shape, 512)
        assert max(shape) / scale <= 512 < max(shape) / max(scale - 1, 1e-9) or scale == 1


def test_the_displayed_image_is_the_area_mean():
    image = (2 * np.arange(16, dtype=np.uint16).reshape(4, 4)) << 4       # Mono12: 8-bit values 0, 2 .. 30
    shown = display_image(image, "Mono12", 2)
    assert shown.shape == (2, 2) and shown.tolist() == [[5, 9], [21, 25]]      # the means of the 2x2 blocks
    assert display_image(image, "Mono12", 1).shape == (4, 4)


def test_every_nth_frames_image_is_drawn():
    pacing = CameraImagePacing(image_every=3)
    assert [pacing.due(k * 10_000_000, behind=False) for k in range(7)] == [True, False, False, True, False,
                                                                             False, True]
    assert pacing.images_above_rate == 0 and pacing.images_left_out == 0


def test_the_rate_limit_follows_the_frames_clock():
    pacing = CameraImagePacing(image_max_hz=25.0)                # at most one image every 40 ms of frame time
    times_ms = [0, 10, 20, 40, 41, 85, 120, 125]
    drawn = [pacing.due(t * 1_000_000, behind=False) for t in times_ms]
    assert drawn == [True, False, False, True, False, True, False, True]
    assert pacing.images_above_rate == 4


def test_a_view_behind_leaves_out_at_most_a_few_images_in_a_row():
    pacing = CameraImagePacing(thin_when_behind=True)
    drawn = [pacing.due(k, behind=True) for k in range(2 * (IMAGE_SKIP_MAX + 1))]
    assert drawn == ([False] * IMAGE_SKIP_MAX + [True]) * 2
    assert pacing.images_left_out == 2 * IMAGE_SKIP_MAX
    assert pacing.due(100, behind=False)                               # caught up: every image again
    unthinned = CameraImagePacing()
    assert all(unthinned.due(k, behind=True) for k in range(10))        # the default never thins
