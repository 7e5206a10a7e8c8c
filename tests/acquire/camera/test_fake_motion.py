"""Tests of acquire/camera/fake_motion.py: images with an exact known motion, and how the fakes serve them."""

import pickle

import numpy as np
import pytest

from livedic.acquire.camera.aravis import open_uri
from livedic.acquire.camera.fake_genicam import InProcessFakeCamera
from livedic.acquire.camera.fake_motion import SpeckleMotion, _triangle, served_as

pytestmark = pytest.mark.usefixtures("time_limit")


def test_the_triangle_wave_has_slope_one_and_stays_within_its_amplitude():
    wave = [_triangle(t, 3) for t in range(14)]
    assert wave == [0, 1, 2, 3, 2, 1, 0, -1, -2, -3, -2, -1, 0, 1]
    assert [_triangle(t, 0) for t in range(4)] == [0, 0, 0, 0]


@pytest.mark.parametrize("bit_depth", [8, 16])
def test_frame_k_is_frame_0_moved_by_its_integer_displacement(bit_depth):
    motion = SpeckleMotion((40, 56), step=(2, -1), max_displacement=5, bit_depth=bit_depth, seed=9)
    reference = motion(0)
    assert reference.shape == (40, 56) and reference.dtype == motion.dtype and reference.std() > 0
    for k in (1, 3, 7, 12):
        u, v = motion.displacement(k)
        assert max(abs(u), abs(v)) <= 5
        image = motion(k)
        # content at (x, y) in frame 0 is at (x + u, y + v) in frame k
        assert np.array_equal(image[5 + v:35 + v, 5 + u:51 + u], reference[5:35, 5:51]), k
    assert [motion.displacement(k) for k in (2, 3, 4)] == [(4, -2), (4, -3), (2, -4)]   # u turns at 5 px


def test_the_same_seed_gives_the_same_images_and_a_pickle_carries_parameters_not_pixels():
    motion = SpeckleMotion((32, 32), seed=4)
    image = motion(2).copy()
    data = pickle.dumps(motion)
    assert len(data) < 2000                                        # no canvas inside
    assert np.array_equal(pickle.loads(data)(2), image) and np.array_equal(SpeckleMotion((32, 32), seed=4)(2), image)
    assert not np.array_equal(SpeckleMotion((32, 32), seed=5)(2), image)
    assert "seed=4" in repr(motion)


@pytest.mark.parametrize("options, words", [
    (dict(shape=(0, 10)), "must be positive"), (dict(step=(1.5, 0)), "must be integers"),
    (dict(bit_depth=12), "must be 8 or 16"), (dict(pattern="plaid"), "'blur' or 'dic'"),
])
def test_bad_parameters_are_value_errors(options, words):
    with pytest.raises(ValueError, match=words):
        SpeckleMotion(**options)


def test_served_as_stretches_8_bits_and_keeps_the_top_bits_of_16():
    eight = np.array([[0, 1, 128, 255]], np.uint8)
    sixteen = np.array([[0, 15, 4096, 65535]], np.uint16)
    assert served_as(eight, 8).tolist() == [[0, 1, 128, 255]] and served_as(eight, 8).dtype == np.uint8
    assert served_as(eight, 16).tolist() == [[0, 257, 32896, 65535]]
    assert served_as(eight, 12).tolist() == [[0, 16, 2055, 4095]] and served_as(eight, 12).dtype == np.uint16
    assert served_as(sixteen, 12).tolist() == [[0, 0, 256, 4095]] and served_as(sixteen, 8).tolist() == [[0, 0, 16, 255]]


def test_the_fill_pattern_pads_a_small_image_and_counts_a_failing_one(aravis):
    small = np.full((10, 12), 200, np.uint8)
    with InProcessFakeCamera(lambda k: small) as fake, open_uri(fake.uri, roi=(0, 0, 32, 16)) as camera:
        image = next(iter(camera)).image
    assert image.shape == (16, 32) and np.all(image[:10, :12] == 200) and np.all(image[10:] == 0)
    assert np.all(image[:, 12:] == 0)

    def broken(k):
        raise RuntimeError("no image")

    with InProcessFakeCamera(broken) as fake, open_uri(fake.uri, roi=(0, 0, 32, 16)) as camera:
        frame = next(iter(camera))
    pattern = fake.patterns[-1]
    assert pattern.errors >= 1 and "no image" in pattern.last_error and frame.image.shape == (16, 32)
