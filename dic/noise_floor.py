"""The measurement's noise floor from static frames, as the iDICs Good Practices Guide (2018) defines it.

Frames of a specimen that does not move (no load, no motion: only the camera's noise changes) measure
what the analysis reads when nothing happens. For each quantity (u, v, exx, eyy, exy, an extensometer's
strain) on F static frames x N points:

* the **spatial SD**: the standard deviation over the points of one frame, then its mean over the frames;
* the **temporal SD**: the standard deviation over the frames of one point, then its mean and its maximum
  over the points;
* the **mean** (the bias): the mean of every value counted; it should be zero within the noise.

Only ok values count (``ok``: the point's status, or NaN values); the counts say how many. Standard deviations
use ``ddof=1``. A spatial SD needs at least two ok points in a frame, a temporal SD two ok frames of a point.
A single-point quantity (an extensometer) has no spatial SD: NaN, its status still OK. One static frame (a
reference and one static image, as many data sets give) has the spatial SD and the mean but no temporal SD:
``NoiseFloorStatus.SPATIAL_ONLY``; no static frame gives NaN everywhere with ``TOO_FEW_FRAMES``; no ok value
at all gives NaN with ``NO_OK_VALUES``. Pure numpy: no I/O.
"""

from __future__ import annotations

import enum
import math
import warnings
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

MICRO = 1e6
MIN_STATIC_FRAMES = 1            # the spatial SD and the mean
MIN_TEMPORAL_FRAMES = 2          # the temporal SD


class NoiseFloorStatus(enum.Enum):
    """Whether a noise floor could be measured, and why not."""
    OK = "ok"
    SPATIAL_ONLY = "spatial_only"
    TOO_FEW_FRAMES = "too_few_frames"
    NO_OK_VALUES = "no_ok_values"

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    NoiseFloorStatus.OK: "measured",
    NoiseFloorStatus.SPATIAL_ONLY: f"one static frame: the spatial SD and mean only (a temporal SD needs "
                                   f"{MIN_TEMPORAL_FRAMES})",
    NoiseFloorStatus.TOO_FEW_FRAMES: "no static frame",
    NoiseFloorStatus.NO_OK_VALUES: "no ok value in the static frames",
}


@dataclass(frozen=True)
class NoiseFloor:
    """One quantity's noise floor over the static frames (see the module notes).

    Attributes
    ----------
    quantity : str
        What was measured: ``u``, ``v``, ``exx``, ``eyy``, ``exy`` or an extensometer's name.
    unit : str
        ``px``, ``mm`` or ``microstrain``.
    spatial_sd : float
        SD over the points of a frame, mean over the frames (NaN for a single point).
    temporal_sd_mean, temporal_sd_max : float
        SD over the frames of a point, mean and maximum over the points.
    mean : float
        Mean of every ok value (the bias).
    frames : int
        Static frames given.
    points : int
        Points with a temporal SD (at least two ok frames).
    values : int
        Ok values counted.
    status : NoiseFloorStatus
    """
    quantity: str
    unit: str
    spatial_sd: float
    temporal_sd_mean: float
    temporal_sd_max: float
    mean: float
    frames: int
    points: int
    values: int
    status: NoiseFloorStatus

    @property
    def ok(self) -> bool:
        return self.status is NoiseFloorStatus.OK

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: NaN as None, the status as its value, plus its ``reason`` in words."""
        out = asdict(self)
        for key, value in out.items():
            if isinstance(value, float) and not math.isfinite(value):
                out[key] = None
        out["status"] = self.status.value
        out["reason"] = self.status.description
        return out

    @classmethod
    def from_dict(cls, item: dict[str, Any]) -> NoiseFloor:
        """Back from ``as_dict`` (None -> NaN)."""
        def number(key: str) -> float:
            value = item.get(key)
            return float("nan") if value is None else float(value)
        return cls(quantity=str(item["quantity"]), unit=str(item["unit"]), spatial_sd=number("spatial_sd"),
                   temporal_sd_mean=number("temporal_sd_mean"), temporal_sd_max=number("temporal_sd_max"),
                   mean=number("mean"), frames=int(item["frames"]), points=int(item["points"]),
                   values=int(item["values"]), status=NoiseFloorStatus(item["status"]))


def noise_floor(values: npt.ArrayLike, ok: npt.ArrayLike | None = None, *, quantity: str, unit: str,
                factor: float = 1.0) -> NoiseFloor:
    """The noise floor of one quantity over static frames (see the module notes).

    Parameters
    ----------
    values : array (F, N) or (F,)
        The quantity in each static frame (rows) at each point (columns); (F,) for a single point.
    ok : array of bool like ``values``, optional
        Which values count (default: the finite ones); a non-finite value never counts.
    quantity, unit : str
        Names for the result.
    factor : float
        Multiplies the values first (1e6 for strain in microstrain, 1 / scale for mm).

    Returns
    -------
    NoiseFloor

    Examples
    --------
    >>> floor = noise_floor([[0.0, 2.0], [2.0, 4.0]], quantity="u", unit="px")
    >>> float(floor.spatial_sd), float(floor.temporal_sd_mean), float(floor.mean)
    (1.4142135623730951, 1.4142135623730951, 2.0)
    """
    data = np.asarray(values, dtype=np.float64)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2:
        raise ValueError(f"values must be (frames, points) or (frames,), got shape {data.shape}")
    good = np.isfinite(data)
    if ok is not None:
        mask = np.asarray(ok, dtype=bool)
        good &= mask.reshape(data.shape) if mask.size == data.size else mask
    frames = data.shape[0]
    nan = float("nan")
    if frames < MIN_STATIC_FRAMES:
        return NoiseFloor(quantity, unit, nan, nan, nan, nan, frames, 0, int(good.sum()),
                          NoiseFloorStatus.TOO_FEW_FRAMES)
    if not good.any():
        return NoiseFloor(quantity, unit, nan, nan, nan, nan, frames, 0, 0, NoiseFloorStatus.NO_OK_VALUES)
    scaled = np.where(good, data * factor, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # all-NaN rows and columns: NaN, dropped below
        per_frame = np.nanstd(scaled, axis=1, ddof=1)
        per_point = np.nanstd(scaled, axis=0, ddof=1)
    per_frame = per_frame[good.sum(axis=1) >= 2]
    per_point = per_point[good.sum(axis=0) >= 2]
    return NoiseFloor(quantity, unit,
                      spatial_sd=float(per_frame.mean()) if per_frame.size else nan,
                      temporal_sd_mean=float(per_point.mean()) if per_point.size else nan,
                      temporal_sd_max=float(per_point.max()) if per_point.size else nan,
                      mean=float(np.nanmean(scaled)), frames=frames, points=int(per_point.size),
                      values=int(good.sum()),
                      status=NoiseFloorStatus.OK if frames >= MIN_TEMPORAL_FRAMES else NoiseFloorStatus.SPATIAL_ONLY)


def field_noise_floor(u: npt.ArrayLike, v: npt.ArrayLike, ok: npt.ArrayLike, *, exx: npt.ArrayLike | None = None,
                      eyy: npt.ArrayLike | None = None, exy: npt.ArrayLike | None = None,
                      strain_ok: npt.ArrayLike | None = None,
                      extensometers: Mapping[str, tuple[npt.ArrayLike, npt.ArrayLike]] | None = None,
                      scale_px_per_mm: float | None = None) -> list[NoiseFloor]:
    """Every quantity's noise floor of one set of static frames, in the order a table shows them.

    Parameters
    ----------
    u, v : arrays (F, N)
        Displacements from the reference, px, in each static frame.
    ok : array (F, N) of bool
        The tracked points' status.
    exx, eyy, exy : arrays (F, N), optional
        Strain (dimensionless; reported in microstrain).
    strain_ok : array (F, N) of bool, optional
        The strain's status (default: the finite values).
    extensometers : {name: (strain (F,), ok (F,))}, optional
        Each extensometer's engineering strain (reported in microstrain).
    scale_px_per_mm : float, optional
        Adds u and v in mm.

    Returns
    -------
    list of NoiseFloor
        u, v (px), u, v (mm, with a scale), exx, eyy, exy, then the extensometers.
    """
    out = [noise_floor(u, ok, quantity="u", unit="px"), noise_floor(v, ok, quantity="v", unit="px")]
    if scale_px_per_mm:
        out += [noise_floor(u, ok, quantity="u", unit="mm", factor=1.0 / scale_px_per_mm),
                noise_floor(v, ok, quantity="v", unit="mm", factor=1.0 / scale_px_per_mm)]
    for name, component in (("exx", exx), ("eyy", eyy), ("exy", exy)):
        if component is not None:
            out.append(noise_floor(component, strain_ok, quantity=name, unit="microstrain", factor=MICRO))
    for name, (strain, good) in (extensometers or {}).items():
        out.append(noise_floor(strain, good, quantity=name, unit="microstrain", factor=MICRO))
    return out
