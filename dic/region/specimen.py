"""The speckled specimen found in an image by its texture (the structure tensor's smaller eigenvalue,
split by Otsu's threshold on its logarithm): ``find_specimen``; the package docstring says why.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from livedic.dic.region.placement import bounding_box

# The structure tensor's window, px: about a speckle and its gap (3-5 px speckles), so that a window
# anywhere on the pattern holds texture in every direction.
TEXTURE_WINDOW = 9
# Texture is measured on the image blurred by this Gaussian (px): a camera's white noise loses ~20x its
# gradient energy, a speckle of 3-5 px a fraction of it, so a noisy background falls away from the speckle.
NOISE_BLUR_SIGMA = 1.0
# Texture below this share of the image's 99th percentile is taken as that floor (exact zeros and float
# rounding on a uniform area would otherwise stretch the logarithm's scale without meaning).
LOG_FLOOR = 1e-3
# Two populations are told apart when Otsu's classes of log10(texture) are at least this far apart
# (decades): speckle against a background, a hole or saturation is 2-4 decades apart on the public
# images; one speckled population split in two by Otsu is less than one decade apart.
SEPARATION_DECADES = 1.0
# With one population (the image is speckle throughout), pixels below this share of its median texture
# are flat: a scratch, a saturated spot.
FLAT_SHARE = 0.02
# A speckled piece is kept when it can hold this many subsets, and is at least this share of the largest.
MIN_PIECE_SUBSETS = 4
MIN_PIECE_SHARE = 0.05


def speckle_texture(image: np.ndarray, window: int = TEXTURE_WINDOW) -> np.ndarray:
    """The smaller eigenvalue of the structure tensor over ``window`` x ``window`` px, (H, W) float32.

    Grey levels^2 / px^2 (central differences): large where the image has texture in every direction,
    ~0 on a uniform area and along a single straight edge.
    """
    import cv2
    f = np.asarray(image, dtype=np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    size = (int(window), int(window))
    a = cv2.boxFilter(gx * gx, -1, size, borderType=cv2.BORDER_REFLECT)
    b = cv2.boxFilter(gx * gy, -1, size, borderType=cv2.BORDER_REFLECT)
    c = cv2.boxFilter(gy * gy, -1, size, borderType=cv2.BORDER_REFLECT)
    half_trace = 0.5 * (a + c)
    radius = np.sqrt(np.maximum(0.25 * (a - c) ** 2 + b * b, 0.0))
    return np.maximum(half_trace - radius, 0.0)


@dataclass(frozen=True)
class Specimen:
    """The speckled part of an image (``find_specimen``).

    Attributes
    ----------
    mask : ndarray (H, W) of bool
        True on the speckled specimen.
    threshold : float
        Texture (``speckle_texture``) above which a pixel counts as speckled.
    separated : bool
        True when the image had two populations (specimen and background, holes, saturation) told apart;
        False when it is speckle throughout (then only flat spots are left out).
    pieces : int
        Speckled pieces kept.
    share : float
        The mask's share of the image.
    """
    mask: np.ndarray = field(repr=False)
    threshold: float
    separated: bool
    pieces: int
    share: float

    @property
    def bounds(self) -> tuple | None:
        """(x, y, w, h) of the mask's bounding box, or None when it is empty."""
        return bounding_box(self.mask)

    def describe(self) -> str:
        bounds = self.bounds
        if bounds is None:
            return "no speckled area found"
        x, y, w, h = bounds
        what = "the speckled specimen" if self.separated else "speckle over the whole image"
        pieces = f" in {self.pieces} pieces" if self.pieces > 1 else ""
        return (f"{what}{pieces}: {100 * self.share:.0f} % of the image, within {x},{y},{w},{h} "
                f"(background, holes and flat or saturated areas left out)")


def _otsu(values: np.ndarray, bins: int = 256) -> float:
    histogram, edges = np.histogram(values, bins=bins)
    centres = 0.5 * (edges[:-1] + edges[1:])
    weight = np.cumsum(histogram).astype(np.float64)
    total = weight[-1]
    mean = np.cumsum(histogram * centres)
    between = (mean[-1] * weight - mean * total) ** 2 / np.maximum(weight * (total - weight), 1e-12)
    return float(centres[int(np.argmax(between[:-1]))])


def find_specimen(image: np.ndarray, subset: int) -> Specimen:
    """The speckled area of ``image``: where a subset can be correlated (module notes).

    Rules, each for a reason:

    1. Texture is ``speckle_texture`` (texture in every direction, over about a speckle) of the image
       blurred by ``NOISE_BLUR_SIGMA`` (a noisy background is not texture that moves with the specimen).
    2. Two populations (a specimen on a background, holes, saturated glare) are told apart by Otsu's
       threshold on log10(texture) when its two classes are at least ``SEPARATION_DECADES`` apart;
       otherwise the image is speckle throughout and only pixels below ``FLAT_SHARE`` of its median
       texture are flat.
    3. The speckled pixels are closed over half a subset (the gaps between speckles of a sparse
       pattern are specimen), opened over a subset (isolated specks of dust or noise on the background
       are not), and their boundary pulled in by half the texture window (the window spreads an edge's
       texture outwards).
    4. Pieces that cannot hold ``MIN_PIECE_SUBSETS`` subsets, or under ``MIN_PIECE_SHARE`` of the
       largest, are dropped.

    Parameters
    ----------
    image : ndarray (H, W)
        The reference frame (any grey dtype).
    subset : int
        Subset side, px: sets the scale of the clean-up.

    Returns
    -------
    Specimen
    """
    import cv2
    smooth = cv2.GaussianBlur(np.asarray(image, dtype=np.float32), (0, 0), NOISE_BLUR_SIGMA,
                              borderType=cv2.BORDER_REPLICATE)
    texture = speckle_texture(smooth)
    top = float(np.percentile(texture[::2, ::2], 99))
    if not top > 0:
        empty = np.zeros(texture.shape, dtype=bool)
        return Specimen(empty, float("inf"), False, 0, 0.0)
    logs = np.log10(np.maximum(texture, LOG_FLOOR * top))
    sample = logs[::2, ::2].ravel()
    split = _otsu(sample)
    low, high = sample[sample <= split], sample[sample > split]
    separated = low.size > 0 and high.size > 0 and float(np.median(high) - np.median(low)) >= SEPARATION_DECADES
    if separated:
        threshold = float(10.0 ** split)
    else:
        threshold = FLAT_SHARE * float(np.median(texture))
    speckled: np.ndarray = (texture > threshold).astype(np.uint8)

    half = max(int(subset) // 2, 1)
    close = np.ones((half | 1, half | 1), np.uint8)
    speckled = cv2.morphologyEx(speckled, cv2.MORPH_CLOSE, close, borderType=cv2.BORDER_REPLICATE)
    opening = np.ones((int(subset) | 1, int(subset) | 1), np.uint8)
    speckled = cv2.morphologyEx(speckled, cv2.MORPH_OPEN, opening, borderType=cv2.BORDER_REPLICATE)
    pull = TEXTURE_WINDOW // 2
    speckled = cv2.erode(speckled, np.ones((2 * pull + 1, 2 * pull + 1), np.uint8), borderType=cv2.BORDER_REPLICATE)

    count, labels, stats, _ = cv2.connectedComponentsWithStats(speckled, connectivity=4)
    areas = stats[1:, cv2.CC_STAT_AREA] if count > 1 else np.zeros(0, dtype=np.int64)
    if areas.size == 0:
        return Specimen(np.zeros(texture.shape, dtype=bool), threshold, separated, 0, 0.0)
    least = max(MIN_PIECE_SUBSETS * int(subset) ** 2, MIN_PIECE_SHARE * float(areas.max()))
    keep = np.flatnonzero(areas >= least) + 1
    mask = np.isin(labels, keep)
    return Specimen(mask, threshold, separated, int(keep.size), float(mask.mean()))
