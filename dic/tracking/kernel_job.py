"""``KernelJob``: one run of the prepared IC-GN kernel (icgn, icgn2) on a frame's window, as ``Tracker``
makes it, so that a caller may run it elsewhere (another thread, another process)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from livedic.dic.bspline import BSplineCoefficients
from livedic.dic.result import SubpixelResult

from livedic.dic.subpixel.icgn import prepare_target
from livedic.dic.subpixel.method import SubpixelMethod


class WindowCoefficients(NamedTuple):
    """A frame's B-spline coefficients on an IC-GN ``window`` (y0, y1, x0, x1), made before ``track`` needs them
    (``Tracker.coefficients_ahead``): valid for any tracker whose window is the same, whatever its reference.
    ``filtered``: the whole frame after the tracker's image pre-filter (``dic.image_filter``), so ``track`` does
    not filter it again; None without a pre-filter."""
    window: tuple[int, int, int, int]
    coefficients: BSplineCoefficients
    filtered: np.ndarray | None = None


def window_coefficients(image: np.ndarray, window: tuple[int, int, int, int],
                        out: BSplineCoefficients | None = None, degree: int = 3) -> BSplineCoefficients:
    """IC-GN's B-spline coefficients (``prepare_target``, of ``degree`` 3 or 5) of ``image``'s rows y0:y1,
    columns x0:x1 (``window``); ``out``: an earlier frame's, overwritten where the window's size is theirs."""
    y0, y1, x0, x1 = window
    return prepare_target(image[y0:y1, x0:x1], out=out, degree=degree)


@dataclass(frozen=True)
class KernelJob:
    """One run of a prepared sub-pixel method's kernel (``method``: IC-GN of either order) as ``Tracker`` makes it.

    ``run(coefficients)`` refines the prepared points ``points`` from (``u0``, ``v0``) and the start
    shape terms ``shape`` (``ux, uy, vx, vy`` and, for icgn2, its second-order terms) with ``order``
    and ``options`` (``refine_prepared``'s), on ``coefficients(frame)``: the frame's ``window``
    (y0, y1, x0, x1), to which the prepared data's positions are relative; ``degree``: of the B-spline
    the frame is sampled with (the tracker's ``interpolation``).
    """
    method: SubpixelMethod
    prep: object
    window: tuple
    points: np.ndarray
    u0: np.ndarray
    v0: np.ndarray
    shape: dict
    order: object
    options: dict
    status: np.ndarray | None = None
    degree: int = 3

    def coefficients(self, image: np.ndarray, out: BSplineCoefficients | None = None) -> BSplineCoefficients:
        """``image``'s coefficients on the window (``window_coefficients``; ``out`` an earlier frame's)."""
        return window_coefficients(image, self.window, out, self.degree)

    def run(self, coefficients: BSplineCoefficients) -> SubpixelResult:
        """The method's sub-pixel result (``SubpixelResult``; icgn2's ``Icgn2Result``) per point of ``points``."""
        starts = {f"{name}0": values for name, values in self.shape.items()}
        return self.method.refine_prepared(self.prep, coefficients, self.u0, self.v0, status=self.status,
                                           points=self.points, order=self.order, **starts, **self.options)
