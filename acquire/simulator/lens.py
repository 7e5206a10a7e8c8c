"""The simulated camera's lens: a pinhole camera (focal length ``LENS_FOCAL_WIDTHS`` x the image width unless
``focal_px`` says otherwise, principal point at the image centre, or ``centre_offset_px`` from it) with OpenCV's distortion k1, k2, p1, p2.

A scene point whose ideal (undistorted) pixel position is X appears in the image at ``distort(X)``;
the image pixel x shows the scene point at ``undistort(x)``. The sources render through it exactly
(every pixel's ideal position computed, not an image warped), and their truth is in image pixels.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.acquire.simulator.options import LENS_FOCAL_WIDTHS, LENS_OPTIONS
from livedic.dic.calibration.camera import distort_pixels, undistort_pixels


@dataclass(frozen=True)
class Lens:
    """A known lens for images of ``size`` (width, height) px: the simulator's truth of a calibration."""

    size: tuple[int, int]
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    focal_px: float | None = None      # None: LENS_FOCAL_WIDTHS x the width (a normal lens)
    # The principal point's offset from the image's centre (px): a real lens's optical centre is rarely the sensor's.
    centre_offset_px: tuple[float, float] = (0.0, 0.0)
    _grid: dict[str, np.ndarray] = field(default_factory=dict, compare=False, repr=False)

    @property
    def camera_matrix(self) -> np.ndarray:
        width, height = self.size
        focal = LENS_FOCAL_WIDTHS * width if self.focal_px is None else self.focal_px
        dx, dy = self.centre_offset_px
        return np.array([[focal, 0.0, (width - 1) / 2.0 + dx], [0.0, focal, (height - 1) / 2.0 + dy],
                         [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV's (k1, k2, p1, p2, k3) with k3 = 0."""
        return np.array([self.k1, self.k2, self.p1, self.p2, 0.0])

    @property
    def distorts(self) -> bool:
        return any((self.k1, self.k2, self.p1, self.p2))

    def distort(self, xy: npt.ArrayLike) -> np.ndarray:
        """Image positions of ideal positions ``xy`` (shape (..., 2))."""
        return distort_pixels(self.camera_matrix, self.dist_coeffs, xy)

    def undistort(self, xy: npt.ArrayLike) -> np.ndarray:
        """Ideal positions of image positions ``xy`` (shape (..., 2)), to 1e-12 px."""
        return undistort_pixels(self.camera_matrix, self.dist_coeffs, xy)

    def ideal_pixels(self, supersample: int = 1) -> np.ndarray:
        """Ideal positions of the pixels' sample points, shape (H s, W s, 2) (computed once per s).

        ``supersample`` s: s x s points evenly spread over each pixel (1: its centre).
        """
        key = f"s{supersample}"
        if key not in self._grid:
            width, height = self.size
            offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
            xs = (np.arange(width)[:, None] + offsets[None, :]).ravel()
            ys = (np.arange(height)[:, None] + offsets[None, :]).ravel()
            x, y = np.meshgrid(xs, ys)
            self._grid[key] = self.undistort(np.stack([x, y], axis=-1))
        return self._grid[key]

    def to_dict(self) -> dict[str, Any]:
        """The lens as the source's settings and specimen state it."""
        return {"camera_matrix": self.camera_matrix.tolist(), "dist_coeffs": self.dist_coeffs.tolist(),
                "focal_px": float(self.camera_matrix[0, 0]), "k1": self.k1, "k2": self.k2, "p1": self.p1,
                "p2": self.p2}


def lens_from_options(options: dict[str, Any]) -> Lens | None:
    """The lens the options ask for, or None for a distortion-free camera (every term 0)."""
    lens = Lens(tuple(options["size"]), *(float(options[name]) for name in LENS_OPTIONS))  # type: ignore[arg-type]
    return lens if lens.distorts else None


def render_through_lens(pattern: Any, lens: Lens, scene_of: Any, *, bit: int = 8, noise: float = 0.0,
                        seed: int = 0) -> np.ndarray:
    """A speckle image as ``lens`` shows a scene, exactly: pixel x shows the pattern's reference point
    ``scene_of(undistort(x))`` (the inverse of the scene's motion, from ideal px to reference px).

    Parameters
    ----------
    pattern : dic.speckle.SpecklePattern
    lens : Lens
    scene_of : callable (xu, yu) -> (X, Y)
        Where the material now at ideal position (xu, yu) was in the reference (float arrays).
    bit, noise, seed
        8 or 12 bit; Gaussian noise SD in grey levels of 8 bit (scaled for 12), its seed.
    """
    from livedic.acquire.simulator.options import FULL_SCALE
    from livedic.acquire.simulator.render import paint, quantise
    ideal = lens.ideal_pixels()
    X, Y = scene_of(ideal[..., 0], ideal[..., 1])
    full = float(FULL_SCALE[bit])
    image = paint(pattern.intensity(X, Y), full).astype(np.float32)
    return quantise(image, bit, noise * full / 255.0, seed)
