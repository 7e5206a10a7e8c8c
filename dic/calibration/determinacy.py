"""How well a camera's calibration images determine its parameters, and the lens model they can carry.

``cv2.calibrateCameraExtended`` gives each parameter's standard deviation (``std_devs``). Two decisions are made
from them, here only:

- ``narrow_field_reason``: a long lens (a narrow field: f 8000 px on 1024 px, a 50 mm lens at 300 mm) sees too
  little perspective to locate its principal point; the fit then wanders tens of px off and k2, p1, p2 bend to
  match (measured: docs/guide/calibration.md, "A stereo rig"). When the principal point's standard deviation
  exceeds ``PRINCIPAL_POINT_LIMIT`` of the image's width, the principal point is fixed at the image's centre and
  k2, p1, p2 at 0 (``NARROW_FIELD_FIXED``), as VIC and MatchID keep fewer distortion terms for long lenses: a
  real lens's centre is within about that distance of the image's, so the centre is the better estimate.
- ``view_spread_deg``: boards (nearly) parallel in every view (less than ``MIN_VIEW_SPREAD_DEG`` apart) determine
  no focal length at all, whatever the standard deviations say: refused.
- ``undetermined``: after that choice, a free parameter that is still poorly determined (the focal length's
  standard deviation in % of it, or a distortion parameter's as its effect at the image's corner, px) above
  ``UncertaintyBounds`` refuses the calibration, naming the parameter and the remedy.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from livedic.dic.calibration.camera import distort_pixels

# The order of cv2.calibrateCameraExtended's stdDeviationsIntrinsics (the first nine of them).
PARAMETERS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
# The principal point is fixed at the image's centre when its standard deviation exceeds this fraction of the
# image's width (10 px on 1024 px): a lens's optical centre is usually that close to the sensor's.
PRINCIPAL_POINT_LIMIT = 0.01
# What a narrow field fixes: the principal point (at the image's centre) and the terms that trade with it there.
NARROW_FIELD_FIXED = ("cx", "cy", "k2", "p1", "p2")
NARROW_FIELD_FLAGS = cv2.CALIB_FIX_PRINCIPAL_POINT | cv2.CALIB_FIX_K2 | cv2.CALIB_ZERO_TANGENT_DIST
# Which parameters a cv2.calibrateCamera flag holds fixed (the rest of PARAMETERS are fitted).
_FIXED_BY_FLAG = ((cv2.CALIB_FIX_PRINCIPAL_POINT, ("cx", "cy")), (cv2.CALIB_FIX_K1, ("k1",)),
                  (cv2.CALIB_FIX_K2, ("k2",)), (cv2.CALIB_FIX_K3, ("k3",)),
                  (cv2.CALIB_ZERO_TANGENT_DIST, ("p1", "p2")))
_DISTORTION = ("k1", "k2", "p1", "p2", "k3")
# Zhang's method needs boards at different tilts: parallel boards leave the focal length free (a long lens's fit
# then settled at f 2800 or 160 px for 8000, with tiny standard deviations and a good RMS). The largest angle between
# two views' boards must reach this.
MIN_VIEW_SPREAD_DEG = 10.0


@dataclass(frozen=True)
class UncertaintyBounds:
    """The largest standard deviations a calibration may leave its free parameters.

    Attributes
    ----------
    focal_percent : float
        Of each focal length, in % of it (well-tilted views give 0.05-0.45 %; at +-0.8 % a long lens's rig came
        out with T 6 mm wrong).
    corner_px : float
        Of each distortion parameter, as its effect on the image's corner (px; good views give 0.1-1.5 px:
        k1 and k2 trade, so each alone is less certain than the undistortion they give together).
    """

    focal_percent: float = 0.5
    corner_px: float = 2.0


DEFAULT_UNCERTAINTY_BOUNDS = UncertaintyBounds()


def free_parameters(flags: int) -> tuple[str, ...]:
    """The parameters ``cv2.calibrateCamera`` fits under ``flags`` (k4-k6 and the thin-prism terms are not used)."""
    fixed = {name for flag, names in _FIXED_BY_FLAG if flags & flag for name in names}
    return tuple(name for name in PARAMETERS if name not in fixed)


def std_devs(std_deviations_intrinsics: np.ndarray, flags: int) -> dict[str, float]:
    """The free parameters' standard deviations by name (``PARAMETERS``) from OpenCV's array."""
    values = np.asarray(std_deviations_intrinsics, dtype=np.float64).ravel()
    return {name: float(values[PARAMETERS.index(name)]) for name in free_parameters(flags)}


def narrow_field_reason(deviations: dict[str, float], image_size: tuple[int, int]) -> str | None:
    """Why the principal point (and the terms trading with it) must be fixed, or None when the views locate it."""
    limit = PRINCIPAL_POINT_LIMIT * image_size[0]
    spread = max(deviations.get("cx", 0.0), deviations.get("cy", 0.0))
    if not spread > limit:
        return None
    return (f"the views locate the principal point to +-{spread:.1f} px only (more than {limit:.0f} px, "
            f"{100 * PRINCIPAL_POINT_LIMIT:g} % of the width: a narrow field): principal point fixed at the image's "
            "centre, k2, p1, p2 at 0")


def view_spread_deg(rvecs: Sequence[np.ndarray]) -> float:
    """The largest angle (degrees) between two views' board normals (boards' poses as rotation vectors)."""
    normals = np.array([cv2.Rodrigues(np.asarray(r, dtype=np.float64))[0][:, 2] for r in rvecs])
    cosines = np.clip(np.abs(normals @ normals.T), 0.0, 1.0)
    return float(np.degrees(np.arccos(np.min(cosines))))


def describe_parallel_views(spread_deg: float) -> str:
    """One line refusing views whose boards are (nearly) parallel, with the remedy."""
    return (f"the boards in the views turn at most {spread_deg:.1f} degrees from one another (under "
            f"{MIN_VIEW_SPREAD_DEG:g}): a calibration needs them tilted 30-40 degrees in several directions, or the "
            "focal length is not determined")


def corner_effects(camera_matrix: np.ndarray, dist_coeffs: np.ndarray, image_size: tuple[int, int],
                   deviations: dict[str, float]) -> dict[str, float]:
    """Each bounded parameter's standard deviation in the unit its bound has: focal lengths in % of them,
    distortion as the shift (px) of the image's corner farthest from the principal point. The principal point's
    own is bounded by the narrow-field rule (``narrow_field_reason``) instead: left free, it is within it."""
    K = np.asarray(camera_matrix, dtype=np.float64)
    dist = np.zeros(5)
    dist[:min(5, np.size(dist_coeffs))] = np.asarray(dist_coeffs, dtype=np.float64).ravel()[:5]
    width, height = image_size
    corners = np.array([[0.0, 0.0], [width - 1.0, 0.0], [0.0, height - 1.0], [width - 1.0, height - 1.0]])
    corner = corners[np.argmax(np.linalg.norm(corners - K[:2, 2], axis=1))]
    seen = distort_pixels(K, dist, corner)
    effects = {}
    for name, sigma in deviations.items():
        if name in ("fx", "fy"):
            effects[name] = 100.0 * sigma / K[PARAMETERS.index(name), PARAMETERS.index(name)]
        elif name in _DISTORTION:
            moved = dist.copy()
            moved[_DISTORTION.index(name)] += sigma
            effects[name] = float(np.linalg.norm(distort_pixels(K, moved, corner) - seen))
    return effects


def undetermined(effects: dict[str, float], bounds: UncertaintyBounds) -> list[tuple[str, float, float]]:
    """(parameter, its standard deviation's effect, the bound) of each parameter above its bound, worst first."""
    over = []
    for name, value in effects.items():
        bound = bounds.focal_percent if name in ("fx", "fy") else bounds.corner_px
        if not value <= bound:         # NaN (a singular fit) is undetermined too
            over.append((name, value, bound))
    return sorted(over, key=lambda item: -item[1] / item[2] if math.isfinite(item[1]) else -math.inf)


def describe_undetermined(name: str, value: float, bound: float) -> str:
    """One clause naming a poorly determined parameter and what the calibration images need."""
    if name in ("fx", "fy"):
        return (f"focal length {name} is determined to +-{value:.2g} % only (bound {bound:g} %): the views need more "
                "tilt (30-40 degrees, in several directions) and more of them, or raise --max-focal-uncertainty")
    return (f"distortion {name} is determined to +-{value:.2g} px at the image's corner only (bound {bound:g} px): the "
            "board must reach the image's corners and edges; use more views, or a larger target, or raise "
            "--max-uncertainty")
