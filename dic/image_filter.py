"""The image pre-filter: a small Gaussian low-pass applied to the reference and to every frame before correlation.

Interpolation bias (the systematic error that depends on the sub-pixel part of the displacement) comes from
the image's content near the Nyquist frequency, which no interpolant reproduces exactly. A Gaussian low-pass
of sigma ~0.4-0.8 px on both images removes most of that content and cuts the bias, at some cost in random
error (Pan et al., "Bias error reduction of digital image correlation using Gaussian pre-filtering",
Opt. Lasers Eng. 51, 2013). docs/guide/measure.md has the measured effect on DIC Challenge 1.0 Sample 3.

``Prefilter.parse`` reads the one textual form ("none" or "gaussian:SIGMA", 0 < SIGMA <= ``MAX_SIGMA``) and is
the only place it is checked; ``Prefilter.apply`` filters one frame (grey, float32 out; none: the frame as given). The kernel is
OpenCV's sampled, normalised Gaussian (``getGaussianKernel``, ``sepFilter2D``), separable, ``2 * ceil(3 sigma) + 1`` taps (at least 5: Pan et al.'s
5 x 5), mirrored at the border without repeating the edge sample (as the B-spline prefilter's mirror).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from livedic.dic.validation import checked_image

NONE = "none"
GAUSSIAN = "gaussian"
DEFAULT_PREFILTER = NONE
# Above 2 px the filter no longer removes only the interpolant's troubles: it blurs the speckles themselves.
MAX_SIGMA = 2.0
# Kernel reach in sigmas: the sampled Gaussian beyond 3 sigma weighs < 1 % of the centre tap.
_REACH_SIGMAS = 3.0
_MIN_HALF_WIDTH = 2
# Image dtypes filtered without a converted copy.
_READ_AS_IS = (np.dtype(np.uint8), np.dtype(np.uint16), np.dtype(np.float32))
FORMS = f"{NONE} or {GAUSSIAN}:SIGMA with 0 < SIGMA <= {MAX_SIGMA:g} px (e.g. {GAUSSIAN}:0.6)"


@dataclass(frozen=True)
class Prefilter:
    """A pre-filter: ``sigma`` None for none, else the Gaussian's standard deviation in pixels.

    ``str(prefilter)`` is its canonical text ("none", "gaussian:0.6"), as recorded and reported.
    """
    sigma: float | None = None

    def __post_init__(self) -> None:
        if self.sigma is not None:
            object.__setattr__(self, "sigma", _checked_sigma(self.sigma, f"{GAUSSIAN}:{self.sigma}"))

    @classmethod
    def parse(cls, text: str | Prefilter | None) -> Prefilter:
        """``"none"`` (or None) or ``"gaussian:SIGMA"``; ValueError (one line) for anything else.

        Examples
        --------
        >>> str(Prefilter.parse("gaussian:0.60"))
        'gaussian:0.6'
        """
        if isinstance(text, Prefilter):
            return text
        if text is None or str(text).strip().lower() == NONE:
            return cls()
        kind, colon, value = str(text).strip().partition(":")
        if kind.lower() != GAUSSIAN or not colon:
            raise ValueError(f"unknown pre-filter {text!r}: give {FORMS}")
        try:
            sigma = float(value)
        except ValueError:
            raise ValueError(f"pre-filter {text!r}: SIGMA must be a number; give {FORMS}") from None
        return cls(_checked_sigma(sigma, text))

    def __str__(self) -> str:
        return NONE if self.sigma is None else f"{GAUSSIAN}:{self.sigma:g}"

    def describe(self) -> str:
        """For people (a report's analysis table): what was applied, and the text that asks for it."""
        if self.sigma is None:
            return NONE
        size = 2 * self.half_width + 1
        return (f"Gaussian low-pass, sigma {self.sigma:g} px ({size} x {size} kernel), on the reference and every "
                f"frame ({self})")

    @property
    def active(self) -> bool:
        """True when it changes images."""
        return self.sigma is not None

    @property
    def half_width(self) -> int:
        """Taps each side of the centre (0 for none): pixels within this distance of the border see the mirror."""
        if self.sigma is None:
            return 0
        return max(_MIN_HALF_WIDTH, math.ceil(_REACH_SIGMAS * self.sigma))

    def kernel(self) -> np.ndarray:
        """The 1-D kernel (float64, sums to 1), applied along rows and then columns."""
        if self.sigma is None:
            return np.ones(1)
        return cv2.getGaussianKernel(2 * self.half_width + 1, self.sigma, cv2.CV_64F).ravel()

    def apply(self, image: np.ndarray) -> np.ndarray:
        """``image`` filtered: a C-contiguous float32 (H, W) array; without a filter, ``image`` as it is (the
        B-spline prefilter reads 8- and 16-bit frames without a converted copy).

        Raises
        ------
        ValueError
            Not a 2-D grey image (with a filter).
        """
        if self.sigma is None:
            return image
        # OpenCV reads 8- and 16-bit frames and writes float32 in one pass (3x faster than converting first)
        frame = checked_image(image, "image")
        frame = np.ascontiguousarray(frame if frame.dtype in _READ_AS_IS else frame.astype(np.float32))
        taps = self.kernel()
        return cv2.sepFilter2D(frame, cv2.CV_32F, taps, taps, borderType=cv2.BORDER_REFLECT_101)


def _checked_sigma(sigma: float, shown: object) -> float:
    """``sigma`` as a float if 0 < sigma <= MAX_SIGMA, else ValueError naming the pre-filter as ``shown``."""
    sigma = float(sigma)
    if not (math.isfinite(sigma) and 0.0 < sigma <= MAX_SIGMA):
        raise ValueError(f"pre-filter {shown!r}: SIGMA must be > 0 and <= {MAX_SIGMA:g} px; give {FORMS}")
    return sigma
