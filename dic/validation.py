"""Checks at the public boundary of ``dic``: bad input raises ``ValueError``
with one line that names the problem and what to do about it."""

import numpy as np
import numpy.typing as npt


def as_image(image: npt.ArrayLike, name: str) -> np.ndarray:
    """Return ``image`` as a C-contiguous float32 2-D array, or raise ValueError."""
    return np.ascontiguousarray(checked_image(image, name), dtype=np.float32)


def checked_image(image: npt.ArrayLike, name: str) -> np.ndarray:
    """Return ``image`` as an array, unconverted, if ``as_image`` takes it, or raise ValueError."""
    array = np.asarray(image)
    if array.ndim != 2:
        raise ValueError(f"{name} image must be 2-D grey (H, W), got shape {array.shape}: convert colour images to grey first")
    if array.dtype.kind not in "uif":
        raise ValueError(f"{name} image has dtype {array.dtype}: give an 8/16-bit integer or float grey image")
    if min(array.shape) < 3:
        raise ValueError(f"{name} image is {array.shape[1]}x{array.shape[0]} pixels: too small to correlate")
    if array.dtype.kind == "f" and not np.all(np.isfinite(array)):
        raise ValueError(f"{name} image contains NaN or infinite pixels: replace them before measuring")
    return array


def check_same_shape(reference: np.ndarray, deformed: np.ndarray) -> None:
    if reference.shape != deformed.shape:
        raise ValueError(
            f"reference is {reference.shape[1]}x{reference.shape[0]} but deformed is "
            f"{deformed.shape[1]}x{deformed.shape[0]}: both images must have the same size")


def check_subset(subset: int, shape: tuple[int, ...]) -> int:
    """Return the half-width of a valid odd ``subset`` side for an image of ``shape``."""
    if isinstance(subset, bool) or not isinstance(subset, (int, np.integer)):
        raise ValueError(f"subset must be an odd integer number of pixels, got {subset!r}")
    if subset < 3 or subset % 2 == 0:
        raise ValueError(f"subset must be an odd integer >= 3 (the point sits at its centre), got {subset}")
    if subset > min(shape):
        raise ValueError(f"subset {subset} is larger than the image ({shape[1]}x{shape[0]}): use a smaller subset")
    return int(subset) // 2


def check_radius(radius: int) -> int:
    if isinstance(radius, bool) or not isinstance(radius, (int, np.integer)) or radius < 0:
        raise ValueError(f"search radius must be a non-negative integer number of pixels, got {radius!r}")
    return int(radius)


def as_points(points: npt.ArrayLike) -> np.ndarray:
    """Return points as float64 (N, 2) of finite (x, y), or raise ValueError."""
    xy = np.asarray(points, dtype=np.float64)
    if xy.ndim == 1 and xy.shape[0] == 2:
        xy = xy[None, :]
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2) holding (x, y), got {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ValueError("points contain NaN or infinite coordinates: give finite (x, y) pixel positions")
    return np.ascontiguousarray(xy)


def as_guess(guess: npt.ArrayLike | None, n_points: int) -> np.ndarray:
    """Return the initial (u, v) guess as float64 (N, 2); NaN rows are allowed (flagged per point)."""
    if guess is None:
        return np.zeros((n_points, 2))
    uv = np.asarray(guess, dtype=np.float64)
    if uv.ndim == 1 and uv.shape[0] == 2:
        uv = np.broadcast_to(uv, (n_points, 2))
    if uv.shape != (n_points, 2):
        raise ValueError(f"guess must be one (u, v) or one per point (shape ({n_points}, 2)), got shape {uv.shape}")
    return np.ascontiguousarray(uv)
