"""P0, the traced point: on the specimen's texture, never a hole or background.

``choose_p0`` places P0 (point 0 of a session) at the best-textured point near
the ROI centre, or assesses a given one; ``P0Choice`` says where and why, for
the session's note, its summary and a warning when P0 is weak.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# Texture is the gradient energy |grad I|^2 (grey levels^2/px^2): its sum over a subset (SSSIG) sets the
# noise of a DIC measurement there. "Local" texture is its mean over 9x9 px, about a speckle and its gap.
_LOCAL_WINDOW = 9
# A pixel is flat where its local texture is below this share of the ROI's 75th percentile: a hole, the
# background or a saturated patch (Sample 12's hole: 0.3 % of it), not the gaps between speckles.
P0_FLAT_LEVEL = 0.02
# A P0 subset is weak when more than this share of it is flat, or when its texture (mean over the subset)
# is below P0_WEAK_TEXTURE times the ROI's median: its trace may follow a hole, an edge or background.
P0_FLAT_SHARE = 0.25
P0_WEAK_TEXTURE = 0.25


class P0Reason(enum.Enum):
    """How P0 was chosen."""
    BEST_NEAR_CENTRE = "best-textured point near the ROI centre"
    MOVED_OFF_WEAK_CENTRE = "the ROI centre has no specimen texture: best-textured point nearest to it"
    NO_TEXTURE = "no textured subset in the ROI: the ROI centre"
    GIVEN = "given with --p0"


@dataclass(frozen=True)
class P0Choice:
    """Where P0 is and why (see ``choose_p0``).

    xy : (x, y) pixel centre of P0
    reason : P0Reason
    relative_texture : P0's subset texture over the ROI's median subset texture (NaN: no texture at all)
    flat_share : share of P0's subset that is flat (hole, background, saturation)
    centre : the ROI centre, pixel
    centre_weak : whether the ROI centre's subset is weak
    radius : the search radius around the centre that found P0 (px; 0 when given)
    """
    xy: tuple[float, float]
    reason: P0Reason
    relative_texture: float
    flat_share: float
    centre: tuple[float, float]
    centre_weak: bool
    radius: int = 0

    @property
    def weak(self) -> bool:
        """P0's subset is partly flat or has little texture: its trace may be wrong."""
        return self.flat_share > P0_FLAT_SHARE or not (self.relative_texture >= P0_WEAK_TEXTURE)

    def _quality(self) -> str:
        texture = "n/a" if not math.isfinite(self.relative_texture) else f"{self.relative_texture:.2f}x"
        return f"texture {texture} the ROI's median, {100 * self.flat_share:.0f} % of its subset flat"

    def describe(self) -> str:
        """Which point, and why, for the session's note."""
        x, y = self.xy
        cx, cy = self.centre
        if self.reason is P0Reason.GIVEN:
            return f"P0 = point 0 at ({x:g}, {y:g}), given with --p0 ({self._quality()})"
        if self.reason is P0Reason.NO_TEXTURE:
            return (f"P0 = point 0 at the ROI centre ({x:g}, {y:g}): the ROI has no textured subset (a blank or "
                    f"out-of-focus image?)")
        if self.reason is P0Reason.MOVED_OFF_WEAK_CENTRE:
            return (f"P0 = point 0 at ({x:g}, {y:g}): the ROI centre ({cx:g}, {cy:g}) is not on specimen texture "
                    f"(a hole, an edge or background), so P0 is the best-textured point within {self.radius} px "
                    f"of it ({self._quality()})")
        return (f"P0 = point 0 at ({x:g}, {y:g}), the best-textured point within {self.radius} px of the ROI "
                f"centre ({cx:g}, {cy:g}) ({self._quality()})")

    def warning(self) -> str | None:
        """A line for the user when P0 is weak, else None."""
        if not self.weak:
            return None
        x, y = self.xy
        if self.reason is P0Reason.GIVEN:
            return (f"P0 ({x:g}, {y:g}) given with --p0 is on weak texture ({self._quality()}): its trace may be "
                    f"wrong; leave out --p0 to let livedic choose a point on the speckle")
        return f"P0 ({x:g}, {y:g}) is on weak texture ({self._quality()}): its trace may be wrong"


def _texture_maps(image: np.ndarray, roi: Sequence[int],
                  subset: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Maps over ``roi`` grown by a subset, indexed [row - y0, column - x0]: (floor, texture, flat, x0, y0).

    floor: the weakest local texture in and around each subset; texture: mean |grad I|^2 over each
    subset; flat: share of each subset that is flat.
    """
    import cv2
    height, width = image.shape
    x, y, w, h = roi
    grow = int(subset)
    x0, y0 = max(x - grow, 0), max(y - grow, 0)
    x1, y1 = min(x + w + grow, width), min(y + h + grow, height)
    crop = np.ascontiguousarray(image[y0:y1, x0:x1], dtype=np.float32)
    gx = cv2.Sobel(crop, cv2.CV_32F, 1, 0, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    gy = cv2.Sobel(crop, cv2.CV_32F, 0, 1, ksize=1, borderType=cv2.BORDER_REPLICATE) * 0.5
    energy = gx * gx + gy * gy
    local = cv2.boxFilter(energy, -1, (_LOCAL_WINDOW, _LOCAL_WINDOW), borderType=cv2.BORDER_REPLICATE)
    inner = local[y - y0:y - y0 + h, x - x0:x - x0 + w]
    level = float(np.percentile(inner[::2, ::2], 75)) if inner.size else 0.0
    size = (int(subset), int(subset))
    flat = cv2.boxFilter((local <= P0_FLAT_LEVEL * level).astype(np.float32), -1, size,
                         borderType=cv2.BORDER_REPLICATE)
    # The weakest local texture around each subset, grown by the local window: the 9x9 means just inside a
    # hole still see its edge (strong), so only the grown window reaches the flat inside of a hole the
    # subset touches.
    grown = int(subset) + _LOCAL_WINDOW - 1
    floor = cv2.erode(local, np.ones((grown, grown), np.uint8), borderType=cv2.BORDER_REPLICATE)
    texture = cv2.boxFilter(energy, -1, size, borderType=cv2.BORDER_REPLICATE)
    return floor, texture, flat, x0, y0


def choose_p0(image: np.ndarray, roi: Sequence[int] | None, subset: int, p0: Sequence[float] | None = None,
              allowed: np.ndarray | None = None, centre: Sequence[float] | None = None) -> P0Choice:
    """P0 on the specimen: the best-textured point near the ROI centre, or the given ``p0`` assessed.

    Without ``p0``: among the pixel centres within a radius of the ROI centre whose
    subset fits in the image, the one whose subset is textured best throughout (the
    largest minimum of the 9x9-px mean |grad I|^2 within the subset; a subset that
    touches a hole, the specimen's edge or background has ~0 there); the radius starts
    at one subset and doubles until a subset with at least ``P0_WEAK_TEXTURE`` times
    the ROI's median of that is found. The ROI centre is often on a hole or on
    background (an open-hole specimen, a wide ROI): those are never chosen. With
    ``p0`` the point is kept and only assessed (``P0Choice.weak``).

    Parameters
    ----------
    image : ndarray (H, W)
        The reference frame.
    roi : tuple (x, y, w, h) or None
        None: the whole image.
    subset : int
        Odd subset side, pixels.
    p0 : (x, y), optional
        A given P0 (snapped to a pixel centre).
    allowed : ndarray (H, W) of bool, optional
        The pixel centres where a point may go (``dic.region.placeable``: its subset inside the region,
        clear of exclusions); P0 is chosen among them. Default: every centre whose subset fits the image.
    centre : (x, y), optional
        Where to look for P0 from (a region that is no rectangle: its middle); default the ROI's centre.

    Returns
    -------
    P0Choice
    """
    height, width = image.shape
    box = tuple(roi) if roi is not None else (0, 0, width, height)
    if centre is None:
        x, y, w, h = box
        centre = (x + (w - 1) / 2.0, y + (h - 1) / 2.0)
    snapped = _pixel_centre(centre)
    field = _TextureField.over(image, box, subset, allowed)
    centre_weak = field.weak(snapped)
    if p0 is not None:
        xy = _pixel_centre(p0)
        return P0Choice(xy, P0Reason.GIVEN, *field.assess(xy), snapped, centre_weak)
    if not field.inside.any() or field.typical_floor <= 0:
        return P0Choice(snapped, P0Reason.NO_TEXTURE, *field.assess(snapped), snapped, centre_weak)
    xy, radius = field.best_near(snapped, subset)
    reason = P0Reason.MOVED_OFF_WEAK_CENTRE if centre_weak else P0Reason.BEST_NEAR_CENTRE
    return P0Choice(xy, reason, *field.assess(xy), snapped, centre_weak, radius)


def _pixel_centre(xy: Sequence[float]) -> tuple[float, float]:
    """The pixel centre nearest to ``xy``."""
    return float(np.floor(xy[0] + 0.5)), float(np.floor(xy[1] + 0.5))


@dataclass(frozen=True)
class _TextureField:
    """The texture maps of ``_texture_maps`` around the ROI, where P0 may go, and their typical values.

    ``inside``: the candidates, pixel centres of the ROI whose subset lies inside the image (and that
    ``allowed`` allows); ``typical_texture`` and ``typical_floor``: the median over them (0 without any).
    """
    floor: np.ndarray
    texture: np.ndarray
    flat: np.ndarray
    x0: int
    y0: int
    inside: np.ndarray
    typical_texture: float
    typical_floor: float

    @classmethod
    def over(cls, image: np.ndarray, roi: Sequence[int], subset: int,
             allowed: np.ndarray | None) -> _TextureField:
        height, width = image.shape
        x, y, w, h = roi
        half = int(subset) // 2
        floor, texture, flat, x0, y0 = _texture_maps(image, (x, y, w, h), subset)
        rows, cols = floor.shape
        cx_lo, cx_hi = max(x, half), min(x + w - 1, width - 1 - half)
        cy_lo, cy_hi = max(y, half), min(y + h - 1, height - 1 - half)
        inside = np.zeros(floor.shape, dtype=bool)
        if cx_lo <= cx_hi and cy_lo <= cy_hi:
            inside[cy_lo - y0:cy_hi - y0 + 1, cx_lo - x0:cx_hi - x0 + 1] = True
        if allowed is not None:
            inside &= allowed[y0:y0 + rows, x0:x0 + cols]
        typical_texture = float(np.median(texture[inside][::3])) if inside.any() else 0.0
        typical_floor = float(np.median(floor[inside][::3])) if inside.any() else 0.0
        return cls(floor, texture, flat, x0, y0, inside, typical_texture, typical_floor)

    def assess(self, xy: tuple[float, float]) -> tuple[float, float]:
        """(relative texture, flat share) of the subset at ``xy``: (NaN, 1) off the maps or without texture."""
        rows, cols = self.floor.shape
        col, row = int(xy[0]) - self.x0, int(xy[1]) - self.y0
        if not (0 <= row < rows and 0 <= col < cols) or self.typical_texture <= 0:
            return float("nan"), 1.0
        return float(self.texture[row, col]) / self.typical_texture, float(self.flat[row, col])

    def weak(self, xy: tuple[float, float]) -> bool:
        relative, flat_share = self.assess(xy)
        return flat_share > P0_FLAT_SHARE or not (relative >= P0_WEAK_TEXTURE)

    def best_near(self, centre: tuple[float, float], subset: int) -> tuple[tuple[float, float], int]:
        """The candidate textured best throughout its subset within a radius of ``centre``, and that radius: one
        subset, doubled until a candidate reaches ``P0_WEAK_TEXTURE`` times the typical floor (or all are in)."""
        row_index, col_index = np.nonzero(self.inside)
        distance2 = (col_index + self.x0 - centre[0]) ** 2 + (row_index + self.y0 - centre[1]) ** 2
        scores = self.floor[row_index, col_index]
        radius = max(int(subset), 1)
        limit = np.sqrt(float(distance2.max()))
        while True:
            near = np.flatnonzero(distance2 <= radius * radius)
            if near.size and (scores[near].max() >= P0_WEAK_TEXTURE * self.typical_floor or radius >= limit):
                break
            radius *= 2
        best = near[int(np.argmax(scores[near]))]        # the first of equals in row-major order: deterministic
        return (float(col_index[best] + self.x0), float(row_index[best] + self.y0)), radius
