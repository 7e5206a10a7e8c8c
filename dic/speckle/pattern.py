"""``SpecklePattern``: seeded Gaussian spot centres over an enlarged domain, their bin grid, and the one
grey-scale factor every image of the pattern uses."""

import math
import numbers

import numpy as np
import numpy.typing as npt

from livedic.dic.speckle.fields import _finite
from livedic.dic.speckle.intensity import _render_float
from livedic.dic.speckle.kernels import _gather_points


# Spots are truncated at CUTOFF * R unless the pattern says otherwise.
DEFAULT_CUTOFF = 5.0
# Fraction of full scale that the brightest reference pixel reaches.
DEFAULT_FILL = 0.8
# Full-scale grey level of each bit depth.
_FULL_SCALE = {8: 255, 12: 4095, 16: 65535}


def _positive_int(value: int, name: str, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value <= 0:
        raise ValueError(f"{name} must be a positive integer ({what}), got {value!r}")
    return int(value)


def _checked_shape(shape: tuple[int, int]) -> tuple[int, int]:
    try:
        H, W = shape
    except (TypeError, ValueError):
        raise ValueError(f"shape must be (H, W), two positive integers, got {shape!r}") from None
    return _positive_int(H, "shape H", "image rows"), _positive_int(W, "shape W", "image columns")


def _checked_spot(radius: float, cutoff: float, fill: float) -> tuple[float, float, float]:
    """The spot's radius, cutoff and fill as floats, or ValueError naming the one out of range."""
    radius = _finite(radius, "radius")
    if radius <= 0.0:
        raise ValueError(f"radius must be > 0 px (R in exp(-d^2/R^2)), got {radius}")
    cutoff = _finite(cutoff, "cutoff")
    if not 3.0 <= cutoff <= 6.0:
        raise ValueError(f"cutoff must be in [3, 6] (units of R; 5 keeps errors near 1e-11), got {cutoff}")
    fill = _finite(fill, "fill")
    if not 0.0 < fill <= 1.0:
        raise ValueError(f"fill must be in (0, 1] (fraction of full scale for the brightest pixel), got {fill}")
    return radius, cutoff, fill


def _count_in_image(H: int, W: int, n_speckles: int | None, density: float | None) -> int:
    """Speckles whose centre lies in the image: from ``density`` or ``n_speckles`` (default 1000)."""
    if density is None:
        return 1000 if n_speckles is None else _positive_int(n_speckles, "n_speckles", "speckles in the image")
    if n_speckles is not None:
        raise ValueError("give either n_speckles or density, not both")
    density = _finite(density, "density")
    if density <= 0.0:
        raise ValueError(f"density must be > 0 speckles per pixel, got {density}")
    n_image = int(round(density * float(H * W)))
    if n_image < 1:
        raise ValueError(f"density {density} gives no speckle in a {W}x{H} image: raise the density")
    return n_image


def _checked_margin(margin: float | None, reach: float, H: int, W: int) -> float:
    """The speckled frame's width (default: the spot's reach, 16 px and a quarter of the image), >= ``reach``."""
    if margin is None:
        margin = math.ceil(reach) + 16 + math.ceil(max(H, W) / 4)
    margin = _finite(margin, "margin")
    if margin < reach:
        raise ValueError(f"margin {margin} px is below the spot cutoff {reach:g} px: the image borders "
                         f"would lack speckles; use margin >= {math.ceil(reach)}")
    return margin


def _draw_centres(seed: int, H: int, W: int, n_image: int, density: float,
                  margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Seeded uniform centres (x, y), sorted by y: ``n_image`` in the image, then the frame around it at the
    same density, drawn by rejection from the whole domain."""
    rng = np.random.default_rng(seed)
    xs_in = rng.uniform(-0.5, W - 0.5, n_image)
    ys_in = rng.uniform(-0.5, H - 0.5, n_image)
    area = float(H * W)
    lo_x, hi_x = -0.5 - margin, W - 0.5 + margin
    lo_y, hi_y = -0.5 - margin, H - 0.5 + margin
    dom_area = (hi_x - lo_x) * (hi_y - lo_y)
    n_frame = int(round(density * (dom_area - area)))
    fx, fy = [], []
    got = 0
    while got < n_frame:
        batch = int(1.2 * (n_frame - got) * dom_area / (dom_area - area)) + 16
        bx = rng.uniform(lo_x, hi_x, batch)
        by = rng.uniform(lo_y, hi_y, batch)
        keep = (bx < -0.5) | (bx >= W - 0.5) | (by < -0.5) | (by >= H - 0.5)
        fx.append(bx[keep])
        fy.append(by[keep])
        got += int(keep.sum())
    xs = np.concatenate([xs_in] + fx)[: n_image + n_frame]
    ys = np.concatenate([ys_in] + fy)[: n_image + n_frame]
    order = np.argsort(ys, kind="stable")
    return np.ascontiguousarray(xs[order]), np.ascontiguousarray(ys[order])


class SpecklePattern:
    """Random Gaussian speckle pattern: seeded centres plus a bin grid.

    Parameters
    ----------
    shape : tuple of int, (H, W)
        Image size in pixels (rows, columns).
    n_speckles : int, optional
        Speckles whose centre lies in the image footprint
        ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``; the margin gets the same density.
        Default 1000 (the paper's 256 x 256 setting) unless ``density`` is given.
    radius : float
        R in ``exp(-d^2 / R^2)``, px (the 1/e half-width; "size 4 px" read as R = 4).
    seed : int
        Seed of ``np.random.default_rng`` for the centres.
    density : float, optional
        Speckles per pixel instead of ``n_speckles`` (handy for large images);
        the image then holds ``round(density * H * W)`` centres.
    margin : float, optional
        Width (px) of the frame around the image that is also filled with
        speckles. A deformed image may sample the reference up to
        ``margin - cutoff * R`` px outside the image. Default
        ``ceil(cutoff * R) + 16 + ceil(max(H, W) / 4)``.
    cutoff : float
        Spots are truncated at ``cutoff * R`` px (default 5: omitted intensity
        about ``exp(-25) = 1.4e-11`` of the mean).
    fill : float
        Fraction of full scale reached by the brightest pixel of the
        point-sampled reference in integer images (default 0.8).

    Attributes
    ----------
    centres : ndarray of float64, shape (N, 2)
        All centres (x, y), image and margin, sorted by y. Read-only.
    n_speckles : int
        Centres inside the image footprint.
    density : float
        Speckles per pixel.
    cutoff_px : float
        Truncation distance ``cutoff * radius`` in px.
    """

    def __init__(self, shape: tuple[int, int] = (256, 256), n_speckles: int | None = None, radius: float = 4.0,
                 seed: int = 0, *, density: float | None = None, margin: float | None = None,
                 cutoff: float = DEFAULT_CUTOFF, fill: float = DEFAULT_FILL) -> None:
        H, W = _checked_shape(shape)
        radius, cutoff, fill = _checked_spot(radius, cutoff, fill)
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        n_image = _count_in_image(H, W, n_speckles, density)
        reach = cutoff * radius
        margin = _checked_margin(margin, reach, H, W)

        self.shape: tuple[int, int] = (H, W)
        self.radius: float = radius
        self.seed: int = int(seed)
        self.n_speckles: int = n_image
        self.density: float = n_image / float(H * W)
        self.margin: float = margin
        self.cutoff: float = cutoff
        self.cutoff_px: float = reach
        self.fill: float = fill

        self._xs: np.ndarray
        self._ys: np.ndarray
        self._xs, self._ys = _draw_centres(self.seed, H, W, n_image, self.density, margin)
        centres = np.stack([self._xs, self._ys], axis=1)
        centres.flags.writeable = False
        self.centres: np.ndarray = centres
        self._bin_centres(reach)
        # Reference points further than this outside the image would see a depleted pattern.
        self._slack = margin - reach
        self._peak: float | None = None

    def _bin_centres(self, reach: float) -> None:
        """The bin grid over the domain (image and margin): cell = cutoff distance, so a disc of the cutoff
        touches <= 3 x 3 cells; the centres sorted by cell (``_gx``, ``_gy``) and each cell's first (``_start``)."""
        H, W = self.shape
        lo_x, hi_x = -0.5 - self.margin, W - 0.5 + self.margin
        lo_y, hi_y = -0.5 - self.margin, H - 0.5 + self.margin
        self._x0, self._y0 = lo_x, lo_y
        self._cell = reach
        self._ncx = max(int(math.ceil((hi_x - lo_x) / reach)), 1)
        self._ncy = max(int(math.ceil((hi_y - lo_y) / reach)), 1)
        cx = np.clip(np.floor((self._xs - lo_x) / reach).astype(np.int64), 0, self._ncx - 1)
        cy = np.clip(np.floor((self._ys - lo_y) / reach).astype(np.int64), 0, self._ncy - 1)
        cell_id = cy * self._ncx + cx
        by_cell = np.argsort(cell_id, kind="stable")
        self._by_cell = by_cell
        self._gx = np.ascontiguousarray(self._xs[by_cell])
        self._gy = np.ascontiguousarray(self._ys[by_cell])
        self._start = np.zeros(self._ncx * self._ncy + 1, dtype=np.int64)
        np.cumsum(np.bincount(cell_id, minlength=self._ncx * self._ncy), out=self._start[1:])

    def __repr__(self) -> str:
        H, W = self.shape
        return (f"SpecklePattern(shape=({H}, {W}), n_speckles={self.n_speckles}, radius={self.radius:g}, "
                f"seed={self.seed}, margin={self.margin:g}, cutoff={self.cutoff:g})")

    @property
    def peak(self) -> float:
        """Brightest pixel of the point-sampled float reference, in units of I0 (float)."""
        if self._peak is None:
            self._peak = float(_render_float(self, None, False).max())
        return self._peak

    def grey_scale(self, bit_depth: int | None) -> float:
        """Grey levels per unit I0 for ``bit_depth`` (8, 12 or 16): one factor for all images (float)."""
        if bit_depth not in _FULL_SCALE:
            raise ValueError(f"bit_depth must be 8, 12, 16 or None, got {bit_depth!r}")
        return self.fill * _FULL_SCALE[bit_depth] / self.peak

    def intensity(self, X: npt.ArrayLike, Y: npt.ArrayLike, amplitudes: npt.ArrayLike | None = None) -> np.ndarray:
        """Reference intensity I(X, Y) (I0 = 1) at arbitrary points, truncated at the cutoff.

        Parameters
        ----------
        X, Y : array_like of float, shape (...)
            Reference coordinates (x = column, y = row), broadcastable.
        amplitudes : array_like of float, shape (N,), optional
            Each spot's amplitude, in ``centres`` order (a faded spot < 1); None: all 1 (the plain sum).

        Returns
        -------
        ndarray of float64, shape (...)
        """
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64))
        shape = X.shape
        X2 = np.ascontiguousarray(X.reshape(1, -1))
        Y2 = np.ascontiguousarray(Y.reshape(1, -1))
        out = np.zeros(X2.shape)
        gx, gy, start, ncx, ncy, x0, y0, cell, inv_r2, reach2 = self._grid_args()
        if amplitudes is None:
            by_cell = np.ones(gx.shape[0])
        else:
            by_cell = np.ascontiguousarray(np.asarray(amplitudes, dtype=np.float64)[self._by_cell])
        _gather_points(X2, Y2, 1.0, gx, gy, by_cell, start, ncx, ncy, x0, y0, cell, inv_r2, reach2, out)
        return out.reshape(shape)

    def _grid_args(self):
        return (self._gx, self._gy, self._start, self._ncx, self._ncy, self._x0, self._y0, self._cell,
                1.0 / (self.radius * self.radius), self.cutoff_px * self.cutoff_px)

    def _tile_args(self):
        return (self._gx, self._gy, self._start, self._ncx, self._ncy, self._x0, self._y0, self._cell,
                1.0 / (self.radius * self.radius), self.cutoff * self.cutoff, self.cutoff_px)

    def _check_inside(self, excess, what):
        if excess > 0.0 or excess != excess:
            need = math.ceil(self.margin + excess) + 1
            raise ValueError(f"{what} samples the reference {excess:.3g} px beyond the speckled margin "
                             f"({self._slack:g} px usable): build the SpecklePattern with margin >= {need}")
