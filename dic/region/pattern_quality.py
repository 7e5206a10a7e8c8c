"""What DIC needs from an image, measured before a test: speckle contrast, saturation, focus, speckle size.

``pattern_quality(image, subset, region)`` maps, per subset, the mean intensity
gradient (MIG, Pan et al. 2010: the mean of |grad I| over the subset, grey levels
per px), the share of clipped pixels (at the bit depth's full scale or at 0), and a
sharpness ratio (the mean |Laplacian| over the MIG, 1/px: defocus takes the fine
detail, curvature, faster than the edges' slope, so this falls where the image is
out of focus; measured on public images blurred by a Gaussian of 1 px: 0.5-0.7 of
the sharp half's value); and, over the region, the speckle size (full width at half
maximum of the pattern's autocorrelation peak) and the displacement noise the MIG
predicts, sigma_u ~ sqrt(2) sigma / (N MIG) for camera noise sigma and an N x N
subset (Pan, Lu, Xie, "Mean intensity gradient: an effective global parameter for
quality assessment of the speckle patterns used in digital image correlation",
Opt. Lasers Eng. 48 (2010) 469-477, doi:10.1016/j.optlaseng.2009.08.010).

Pure functions on numpy arrays (OpenCV filters); the advice thresholds are the
constants below, each with its reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PatternQuality", "pattern_quality", "full_scale"]

# A speckle spans a few pixels: below this FWHM the pattern aliases (sub-pixel bias grows). A subset should
# hold at least 3 speckles across (Sutton, Orteu, Schreier, "Image correlation for shape, motion and
# deformation measurements", 2009); the warning comes below 2.5, leaving room for the size's estimate.
MIN_SPECKLE_PX = 2.5
MIN_SPECKLES_ACROSS = 2.5
RECOMMENDED_SPECKLES_ACROSS = 3
# Clipped pixels carry no gradient and move with the light, not the specimen: more than this share of the
# region is worth a new exposure.
MAX_CLIPPED_SHARE = 0.005
# A subset is weak when its MIG is below this share of the region's median: too little contrast there.
WEAK_SUBSET_SHARE = 0.25
# Sharpness varying by more than this factor across the region (``_focus_spread``): part of the specimen
# is out of the depth of field (a tilted coupon, a lens focused in front of or behind it). Measured on the
# public images of ../shared/datasets: 1.04-1.14 as they are, 1.39-2.03 with one half blurred by a 1 px
# Gaussian (1.21-1.72 by 0.7 px).
FOCUS_SPREAD = 1.3
# The autocorrelation is measured on a central patch of at most this side (px).
AUTOCORRELATION_PATCH = 256


def full_scale(image: np.ndarray, bit_depth: int | None = None) -> int:
    """The image's full-scale grey level: 2**bit_depth - 1, else the dtype's (255, 65535)."""
    if bit_depth:
        return (1 << int(bit_depth)) - 1
    return 255 if image.dtype == np.uint8 else 65535 if image.dtype == np.uint16 else int(np.nanmax(image))


@dataclass(frozen=True)
class PatternQuality:
    """The maps and figures of ``pattern_quality``.

    Attributes
    ----------
    mig : ndarray (H, W) float32
        Mean |grad I| over the subset centred on each pixel, grey levels / px.
    sharpness : ndarray (H, W) float32
        Mean |Laplacian| over the MIG in the subset, 1/px (NaN where the subset is flat).
    clipped : ndarray (H, W) bool
        Pixels at full scale (saturated) or at 0 (underexposed).
    region : ndarray (H, W) bool
        Where the figures below are taken (the specimen, the ROI).
    mig_median : float
        Median MIG over the region's subsets.
    clipped_share : float
        Share of the region's pixels that are clipped.
    speckle_px : float
        Speckle size, px (NaN: not measurable): the FWHM of a speckle, from the autocorrelation peak of a
        central patch of the region (whose FWHM is sqrt(2) times a Gaussian speckle's).
    sharpness_spread : float
        How much the sharpness varies across the region (``_focus_spread``; 1 = even focus).
    subset : int
    full_scale : int
        The grey level of saturation.
    """
    mig: np.ndarray = field(repr=False)
    sharpness: np.ndarray = field(repr=False)
    clipped: np.ndarray = field(repr=False)
    region: np.ndarray = field(repr=False)
    mig_median: float
    clipped_share: float
    speckle_px: float
    sharpness_spread: float
    subset: int
    full_scale: int

    def noise_per_grey_level(self) -> float:
        """Predicted displacement noise (px) per grey level of camera noise: sqrt(2) / (N MIG)."""
        if not self.mig_median > 0:
            return float("nan")
        return math.sqrt(2.0) / (self.subset * self.mig_median)

    def weak_subsets(self, points: np.ndarray) -> np.ndarray:
        """Boolean (N,): points whose subset's MIG is below ``WEAK_SUBSET_SHARE`` of the median."""
        xy = np.floor(np.asarray(points, dtype=np.float64) + 0.5).astype(np.int64)
        height, width = self.mig.shape
        xs, ys = np.clip(xy[:, 0], 0, width - 1), np.clip(xy[:, 1], 0, height - 1)
        return self.mig[ys, xs] < WEAK_SUBSET_SHARE * self.mig_median

    def advice(self) -> list:
        """One line per problem found (empty when the pattern, exposure and focus look fit for DIC)."""
        lines = []
        if self.clipped_share > MAX_CLIPPED_SHARE:
            lines.append(f"{100 * self.clipped_share:.1f} % of the specimen's pixels are clipped (at 0 or at "
                         f"{self.full_scale}): lower the exposure or gain (or raise it, if they are at 0)")
        if math.isfinite(self.speckle_px):
            if self.speckle_px < MIN_SPECKLE_PX:
                lines.append(f"speckles of {self.speckle_px:.1f} px are smaller than {MIN_SPECKLE_PX:g} px: they "
                             f"alias (sub-pixel bias); use a coarser pattern or more magnification")
            elif self.subset / self.speckle_px < MIN_SPECKLES_ACROSS:
                lines.append(f"speckles of {self.speckle_px:.1f} px are large for a {self.subset} px subset "
                             f"({self.subset / self.speckle_px:.1f} across it): use --subset "
                             f"{_odd(RECOMMENDED_SPECKLES_ACROSS * self.speckle_px)} or a finer pattern")
        if self.sharpness_spread > FOCUS_SPREAD:
            lines.append(f"sharpness varies {self.sharpness_spread:.1f}x across the specimen: part of it is out of "
                         f"focus (check the focus and that the specimen faces the camera)")
        return lines

    def describe(self) -> list:
        """The figures, one line each, for a person setting up a test."""
        noise = self.noise_per_grey_level()
        lines = [f"speckle contrast: mean intensity gradient (MIG) {self.mig_median:.1f} grey levels/px (median over "
                 f"{self.subset} px subsets); predicted displacement noise {noise:.4f} px per grey level of camera "
                 f"noise (sqrt(2) sigma / (N MIG), Pan et al. 2010)"]
        size = "n/a" if not math.isfinite(self.speckle_px) else \
            f"{self.speckle_px:.1f} px, {self.subset / self.speckle_px:.1f} across a subset"
        lines.append(f"speckle size {size} (FWHM from the autocorrelation; 3-5 px speckles and at least "
                     f"{RECOMMENDED_SPECKLES_ACROSS} across a subset are best); clipped pixels "
                     f"{100 * self.clipped_share:.2f} %; sharpness spread {self.sharpness_spread:.2f}x (1 = even focus)")
        return lines


def _odd(value: float) -> int:
    n = int(math.ceil(value))
    return n if n % 2 else n + 1


def _speckle_size(image: np.ndarray, region: np.ndarray) -> float:
    """Speckle FWHM (px): the autocorrelation peak's FWHM over the largest square patch around the region's
    centre (up to ``AUTOCORRELATION_PATCH``), over sqrt(2)."""
    from livedic.dic.region.placement import placeable
    per_row, per_column = region.sum(axis=1), region.sum(axis=0)
    total = float(per_row.sum())
    if total == 0:
        return float("nan")
    cy = int(round(float(per_row @ np.arange(per_row.size)) / total))
    cx = int(round(float(per_column @ np.arange(per_column.size)) / total))
    half = AUTOCORRELATION_PATCH // 2
    while half >= 16:
        fits = placeable(region, 2 * half + 1)          # centres of patches wholly in the region
        if fits[cy, cx]:
            y0, x0 = cy - half, cx - half
            break
        coarse = 8                                      # the nearest fitting centre, looked for every 8 px
        ys, xs = np.nonzero(fits[::coarse, ::coarse])
        if ys.size:
            nearest = int(np.argmin((coarse * ys - cy) ** 2 + (coarse * xs - cx) ** 2))
            y0, x0 = coarse * int(ys[nearest]) - half, coarse * int(xs[nearest]) - half
            break
        half //= 2
    else:
        return float("nan")
    patch = np.asarray(image[y0:y0 + 2 * half, x0:x0 + 2 * half], dtype=np.float64)
    patch = patch - patch.mean()
    if not np.any(patch):
        return float("nan")
    window = np.outer(np.hanning(patch.shape[0]), np.hanning(patch.shape[1]))
    spectrum = np.fft.fft2(patch * window)
    correlation = np.fft.fftshift(np.fft.ifft2(np.abs(spectrum) ** 2).real)
    correlation /= correlation.max()
    centre = correlation.shape[0] // 2
    widths = []
    for profile in (correlation[centre, centre:], correlation[centre:, centre]):
        below = np.flatnonzero(profile < 0.5)
        if below.size == 0:
            return float("nan")
        k = int(below[0])          # interpolate the half-maximum crossing between k - 1 and k
        widths.append(2.0 * (k - 1 + (profile[k - 1] - 0.5) / (profile[k - 1] - profile[k])))
    return float(np.mean(widths)) / math.sqrt(2.0)


def _focus_spread(sharpness: np.ndarray, region: np.ndarray, tile: int) -> float:
    """90th over 10th percentile of the median sharpness of ``tile``-px tiles mostly in the region.

    Per subset the ratio varies with the pattern itself; the medians of tiles of a few subsets keep only what varies
    smoothly across the image, as focus does.
    """
    height, width = sharpness.shape
    rows, columns = height // tile, width // tile
    if rows == 0 or columns == 0:
        return float("nan")

    def tiles(array):
        return array[:rows * tile, :columns * tile].reshape(rows, tile, columns, tile).swapaxes(1, 2).reshape(
            rows * columns, tile * tile)

    inside = tiles(region)
    values = np.where(inside & np.isfinite(tiles(sharpness)), tiles(sharpness), np.nan)
    kept = (inside.mean(axis=1) >= 0.9) & np.isfinite(values).any(axis=1)
    medians = np.nanmedian(values[kept], axis=1) if kept.any() else np.zeros(0)
    if len(medians) < 4:
        return float("nan")
    low, high = np.percentile(medians, [10, 90])
    return float(high / low) if low > 0 else float("nan")


def pattern_quality(image: np.ndarray, subset: int, region: np.ndarray | None = None, *,
                    bit_depth: int | None = None) -> PatternQuality:
    """The speckle pattern's fitness for DIC (module notes).

    Parameters
    ----------
    image : ndarray (H, W)
        The reference frame (any grey dtype).
    subset : int
        Subset side, px: the maps are per subset.
    region : ndarray (H, W) of bool, optional
        Where to take the figures (the specimen); default the whole image.
    bit_depth : int, optional
        Significant bits (a 12-bit camera in 16-bit frames saturates at 4095); default the dtype's.
    """
    import cv2
    f = np.asarray(image, dtype=np.float32)
    region = np.ones(f.shape, dtype=bool) if region is None else np.asarray(region, dtype=bool)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    size = (int(subset), int(subset))
    mig = cv2.boxFilter(np.sqrt(gx * gx + gy * gy), -1, size, borderType=cv2.BORDER_REFLECT)
    laplacian = cv2.boxFilter(np.abs(cv2.Laplacian(f, cv2.CV_32F, ksize=1, borderType=cv2.BORDER_REPLICATE)), -1,
                              size, borderType=cv2.BORDER_REFLECT)
    with np.errstate(divide="ignore", invalid="ignore"):
        sharpness = np.where(mig > 1e-3, laplacian / mig, np.nan).astype(np.float32)
    top = full_scale(image, bit_depth)
    clipped = (f >= top) | (f <= 0)
    inside = region if region.any() else np.ones(f.shape, dtype=bool)
    mig_median = float(np.median(mig[inside]))
    spread = _focus_spread(sharpness, inside, 3 * int(subset))
    return PatternQuality(mig=mig, sharpness=sharpness, clipped=clipped, region=inside, mig_median=mig_median,
                          clipped_share=float(clipped[inside].mean()), speckle_px=_speckle_size(f, inside),
                          sharpness_spread=spread, subset=int(subset), full_scale=top)
