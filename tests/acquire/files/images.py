"""Test images of the file-source tests and how they are written (helpers, not tests)."""

import cv2
import numpy as np

RNG = np.random.default_rng(7)
GREY8 = RNG.integers(0, 256, (37, 53), dtype=np.uint8)
GREY16 = RNG.integers(0, 65536, (37, 53), dtype=np.uint16)
COLOUR = RNG.integers(0, 256, (37, 53, 3), dtype=np.uint8)


def write(path, image):
    """``image`` written by OpenCV at ``path`` (the format from its extension); returns the path as a str."""
    assert cv2.imwrite(str(path), image), path
    return str(path)
