import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


def blurred_noise(shape, seed=0, sigma=2.0):
    """A random texture that is not the simulator: keeps correlation tests independent of it."""
    import cv2
    noise = np.random.default_rng(seed).uniform(0, 255, size=shape).astype(np.float32)
    return cv2.GaussianBlur(noise, (0, 0), sigma)
