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
at all gives NaN with ``NO_OK_VALUES``.

**Stereo** (static pairs): the 3D displacements U, V, W (mm) have the same three statistics, in the specimen's axes
(``dic.stereo.specimen_frame``: U, V in its best-fit plane, W along its normal), fitted to the reference pair's
points (each ok point's X - U, the same in every pair): the depth noise of a rig with half-angle a between its
cameras is about 1 / tan(a) times the in-plane noise, and in the left camera's axes it would leak into X. X, Y, Z
have no rows of their own: the reference is fixed, so their SD over the pairs is U, V, W's. Fewer than 3 ok
points give no plane: NaN with ``NO_SPECIMEN_PLANE``. Only ok 3D points count (``StereoPoints.ok``); the surface
strain and the extensometers in space are the 2D rows' statistics on their stereo values. Pure numpy: no I/O.
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
    NO_SPECIMEN_PLANE = "no_specimen_plane"

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    NoiseFloorStatus.OK: "measured",
    NoiseFloorStatus.SPATIAL_ONLY: f"one static frame: the spatial SD and mean only (a temporal SD needs "
                                   f"{MIN_TEMPORAL_FRAMES})",
    NoiseFloorStatus.TOO_FEW_FRAMES: "no static frame",
    NoiseFloorStatus.NO_OK_VALUES: "no ok value in the static frames",
    NoiseFloorStatus.NO_SPECIMEN_PLANE: "fewer than 3 points in 3D: no specimen plane to give U, V, W their axes",
}
# The 3D displacements' quantities, in the specimen's axes (module notes).
DISPLACEMENT_3D = ("U", "V", "W")


@dataclass(frozen=True)
class NoiseFloor:
    """One quantity's noise floor over the static frames (see the module notes).

    Attributes
    ----------
    quantity : str
        What was measured: ``u``, ``v``, ``U``, ``V``, ``W`` (stereo), ``exx``, ``eyy``, ``exy`` or an
        extensometer's name.
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
                      scale_px_per_mm: float | None = None, xyz_mm: npt.ArrayLike | None = None,
                      displacement_mm: npt.ArrayLike | None = None, ok_3d: npt.ArrayLike | None = None
                      ) -> list[NoiseFloor]:
    """Every quantity's noise floor of one set of static frames (or pairs), in the order a table shows them.

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
    xyz_mm, displacement_mm : arrays (F, N, 3), optional
        Stereo: each static pair's 3D points and displacements from the reference pair (mm, any one frame's axes,
        ``StereoPoints.xyz`` and ``.displacement``); adds U, V, W (mm) in the specimen's axes
        (``displacement_3d_noise_floor``).
    ok_3d : array (F, N) of bool, optional
        The 3D points' status (``StereoPoints.ok``; default: the finite ones).

    Returns
    -------
    list of NoiseFloor
        u, v (px), u, v (mm, with a scale), U, V, W (mm, stereo), exx, eyy, exy, then the extensometers.
    """
    out = [noise_floor(u, ok, quantity="u", unit="px"), noise_floor(v, ok, quantity="v", unit="px")]
    if scale_px_per_mm:
        out += [noise_floor(u, ok, quantity="u", unit="mm", factor=1.0 / scale_px_per_mm),
                noise_floor(v, ok, quantity="v", unit="mm", factor=1.0 / scale_px_per_mm)]
    if displacement_mm is not None:
        if xyz_mm is None:
            raise ValueError("the 3D displacements need their 3D points (xyz_mm) for the specimen's axes")
        out += displacement_3d_noise_floor(xyz_mm, displacement_mm, ok_3d)
    for name, component in (("exx", exx), ("eyy", eyy), ("exy", exy)):
        if component is not None:
            out.append(noise_floor(component, strain_ok, quantity=name, unit="microstrain", factor=MICRO))
    for name, (strain, good) in (extensometers or {}).items():
        out.append(noise_floor(strain, good, quantity=name, unit="microstrain", factor=MICRO))
    return out


def specimen_axes(xyz_mm: npt.ArrayLike, displacement_mm: npt.ArrayLike, ok: npt.ArrayLike) -> np.ndarray | None:
    """The specimen frame's rotation (rows: its x, y and normal; ``dic.stereo.specimen_frame``) fitted to the
    reference pair's points, X - U of every ok point of the static pairs; None below 3 such points."""
    from livedic.dic.stereo.frame import specimen_frame
    reference = np.asarray(xyz_mm, dtype=np.float64) - np.asarray(displacement_mm, dtype=np.float64)
    good = np.asarray(ok, dtype=bool) & np.all(np.isfinite(reference), axis=-1)
    if not good.any():
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)     # a point ok in no pair: NaN, left out by the fit
        points = np.nanmean(np.where(good[..., None], reference, np.nan), axis=0)
    try:
        return specimen_frame(points).rotation
    except ValueError:                                       # fewer than 3 points, or on a line
        return None


def displacement_3d_noise_floor(xyz_mm: npt.ArrayLike, displacement_mm: npt.ArrayLike,
                                ok: npt.ArrayLike | None = None) -> list[NoiseFloor]:
    """U, V, W's noise floor (mm) over static pairs, in the specimen's axes (see the module notes).

    Parameters
    ----------
    xyz_mm, displacement_mm : arrays (F, N, 3)
        Each static pair's 3D points and displacements from the reference pair (mm, the left camera's axes).
    ok : array (F, N) of bool, optional
        The 3D points' status (default: the finite ones).

    Returns
    -------
    list of NoiseFloor
        U, V, W: NaN with ``NO_SPECIMEN_PLANE`` where fewer than 3 ok points give no plane.

    Examples
    --------
    >>> xyz = np.array([[[0.0, 0, 300], [10, 0, 300], [0, 10, 300], [10, 10, 300]]] * 2)
    >>> moved = np.zeros_like(xyz); moved[1, :, 2] = [0.0, 0.002, 0.004, 0.002]
    >>> [round(f.temporal_sd_max, 6) for f in displacement_3d_noise_floor(xyz + moved, moved)]
    [0.0, 0.0, 0.002828]
    """
    displacement = np.asarray(displacement_mm, dtype=np.float64)
    xyz = np.asarray(xyz_mm, dtype=np.float64)
    if displacement.ndim != 3 or displacement.shape[-1] != 3 or xyz.shape != displacement.shape:
        raise ValueError(f"3D points and displacements must both be (pairs, points, 3), got {xyz.shape} and "
                         f"{displacement.shape}")
    good = np.all(np.isfinite(displacement), axis=-1)
    if ok is not None:
        good &= np.asarray(ok, dtype=bool).reshape(good.shape)
    axes = specimen_axes(xyz, displacement, good) if displacement.shape[0] else None
    if axes is None:
        nan = float("nan")
        status = NoiseFloorStatus.TOO_FEW_FRAMES if displacement.shape[0] < MIN_STATIC_FRAMES else \
            NoiseFloorStatus.NO_SPECIMEN_PLANE
        return [NoiseFloor(name, "mm", nan, nan, nan, nan, displacement.shape[0], 0, int(good.sum()), status)
                for name in DISPLACEMENT_3D]
    turned = displacement @ axes.T
    return [noise_floor(turned[..., i], good, quantity=name, unit="mm") for i, name in enumerate(DISPLACEMENT_3D)]
