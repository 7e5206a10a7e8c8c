"""The simulated tensile test's exact mechanics (no pixels): ``TensileModel`` (displacement, force law,
visibility, fracture) and ``FrameTruth``, one frame's exact displacement of reference points.

The model's equations: docs/guide/sources.md ("The tensile test").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.options import (DEFAULT_MODULUS_GPA, DEFAULT_SCALE_PX_PER_MM, DEFAULT_THICKNESS_MM,
                                               LATERAL_LAWS, VIEWS)


# --------------------------------------------------------------------------- #
# The tensile model (pure maths, no pixels)
# --------------------------------------------------------------------------- #

def _logcosh(z):
    a = np.abs(z)
    return a + np.log1p(np.exp(-2.0 * a)) - math.log(2.0)


def _sech2(z):
    return 1.0 / np.cosh(np.clip(z, -350.0, 350.0)) ** 2


class TensileModel:
    """Exact Lagrangian displacement of a dog-bone coupon under tension (docs/guide/sources.md, "The tensile test").

    Parameters
    ----------
    shape : tuple of int, (H, W)
        Image size, rows and columns.
    frames : int
        Frames of the test; frame 0 is the undeformed reference, the last one the deepest neck
        (or, with ``fracture_frame``, the last one before the fracture).
    strain : float
        Uniform plastic strain reached when the neck starts.
    neck : float
        Extra peak strain at the centre of the neck in the last frame (before the fracture).
    seed : int
        Seed of the grip jitter.
    lateral : {"linear", "incompressible"}
        Law of the lateral contraction: ``linear`` (dU/dX = -(0.3 e_el + 0.5 e_p), the small-strain
        law of the default test) or ``incompressible`` (width stretch (1 - 0.3 e_el) / sqrt(1 + e_p):
        plastic flow keeps the volume at any strain).
    view : {"grip", "centre"}
        ``grip``: the bottom grip line stays put in the image; ``centre``: the camera keeps the
        deformed gauge section centred (the mid-point of its two ends stays where it was).
    fracture_frame : int or None
        First frame in which the specimen is broken across the neck centre (2 <= F < frames), or
        None for no fracture.
    modulus_gpa : float
        Young's modulus E (GPa): the gauge section's engineering stress is E x e_el (docs/guide/sources.md, Force).
    hardening : float
        h >= 0: e_el grows linearly with the uniform plastic strain to (1 + h) x 0.004 when the neck
        starts (linear hardening; it changes the displacement, so the images). 0: perfectly plastic.
    upper_yield : float
        u >= 0: an upper yield point. The elastic line rises to (1 + u) x the yield strain, and the
        elastic strain falls back to it over the first ``UPPER_YIELD_DROP`` of the uniform plastic
        phase (the force drops when the Lueders band forms; ISO 6892-1 ReH = (1 + u) yield, ReL =
        yield). 0: none (the default test's frames stay as they were).
    thickness_mm, scale_px_per_mm : float
        Thickness of the coupon and the camera's scale: A0 = gauge width (px) / scale x thickness.

    Attributes
    ----------
    x_centre, y_neck, neck_width, gauge_top, gauge_bottom, gauge_half, shoulder_half, y_grip : float
        Geometry in reference pixels (``y_grip`` is the fixed bottom grip line). ``y_neck`` is also
        the reference row of the crack.
    fracture_frame : int or None
    """

    NU_ELASTIC = 0.3
    NU_PLASTIC = 0.5
    YIELD_STRAIN = 0.004
    TAU_YIELD = 0.15
    TAU_NECK = 0.6
    UNLOAD = 0.2           # elastic strain lost outside the neck once it forms (fraction)
    UPPER_YIELD_DROP = 0.02  # share of the uniform plastic phase over which the force falls from ReH to ReL
    JITTER_PX = 0.03       # grip jitter, standard deviation per frame and axis
    DRIFT_PX = (0.25, 0.15)  # (u, v) drift of both grips over the whole test
    SHEAR_PX = -0.4        # extra sideways drift of the top grip over the whole test
    GAP_START_PX = 3.0     # opening of the crack in the fracture frame
    GAP_RATE_PX = 2.0      # further opening per frame after it
    LATERAL_LAWS = LATERAL_LAWS
    VIEWS = VIEWS

    def __init__(self, shape: tuple[int, int], frames: int, *, strain: float = 0.05, neck: float = 0.15, seed: int = 0,
                 lateral: str = "linear", view: str = "grip", fracture_frame: int | None = None,
                 modulus_gpa: float = DEFAULT_MODULUS_GPA, hardening: float = 0.0, upper_yield: float = 0.0,
                 thickness_mm: float = DEFAULT_THICKNESS_MM, scale_px_per_mm: float = DEFAULT_SCALE_PX_PER_MM) -> None:
        H, W = int(shape[0]), int(shape[1])
        self.shape = (H, W)
        self.frames = int(frames)
        self.plastic_strain = float(strain)
        self.neck_strain = float(neck)
        self.seed = int(seed)
        if lateral not in self.LATERAL_LAWS:
            raise ValueError(f"lateral must be one of {', '.join(self.LATERAL_LAWS)}, got {lateral!r}")
        if view not in self.VIEWS:
            raise ValueError(f"view must be one of {', '.join(self.VIEWS)}, got {view!r}")
        if fracture_frame is not None and not 2 <= int(fracture_frame) <= self.frames - 1:
            raise ValueError(f"the fracture frame must be in 2..{self.frames - 1} (frames={self.frames}), "
                             f"got {fracture_frame}")
        for name, value in (("modulus_gpa", modulus_gpa), ("thickness_mm", thickness_mm),
                            ("scale_px_per_mm", scale_px_per_mm)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        for name, value in (("hardening", hardening), ("upper_yield", upper_yield)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        self.upper_yield = float(upper_yield)
        self.modulus_gpa = float(modulus_gpa)
        self.hardening = float(hardening)
        self.thickness_mm = float(thickness_mm)
        self.scale_px_per_mm = float(scale_px_per_mm)
        self.lateral = lateral
        self.view = view
        self.fracture_frame = None if fracture_frame is None else int(fracture_frame)
        self.x_centre = (W - 1) / 2.0
        self.gauge_half = 0.20 * W
        self.shoulder_half = 0.35 * W
        self.gauge_top = 0.18 * H
        self.gauge_bottom = 0.82 * H
        self.fillet = 0.035 * H        # tanh width of the gauge/shoulder transition (outline)
        self.box_edge = 0.035 * H      # tanh width of the plastic zone's ends (as the fillet)
        self.y_neck = 0.44 * H         # neck centre: 0.06 H above the image centre
        self.neck_width = 0.07 * H     # s in sech^2((Y - Y_n) / s)
        self.y_grip = H - 1.0
        self.area_ratio = self.gauge_half / self.shoulder_half
        rng = np.random.default_rng([self.seed, 2024])
        jitter = rng.normal(0.0, self.JITTER_PX, size=(self.frames, 2))
        jitter[0] = 0.0
        self._jitter = jitter

    # -- schedule ---------------------------------------------------------
    def tau(self, i: int) -> float:
        """Normalised time of the loading schedule: 0 at frame 0, 1 at the last frame before any fracture."""
        if self.fracture_frame is None:
            return i / max(self.frames - 1, 1)
        return min(i, self.fracture_frame - 1) / (self.fracture_frame - 1)

    def fractured(self, i: int) -> bool:
        """Whether frame ``i`` shows the specimen broken."""
        return self.fracture_frame is not None and i >= self.fracture_frame

    def state(self, i: int) -> dict[str, Any]:
        """Strains and rigid motion of frame ``i`` (a dict of floats; ``gap`` is the crack opening, px)."""
        tau = self.tau(i)
        if tau <= self.TAU_YIELD:
            e_el = self.YIELD_STRAIN * (1.0 + self.upper_yield) * tau / self.TAU_YIELD
            e_pl = 0.0
            e_n = 0.0
            phase = "elastic"
        elif tau <= self.TAU_NECK:
            progress = (tau - self.TAU_YIELD) / (self.TAU_NECK - self.TAU_YIELD)
            e_el = self.YIELD_STRAIN
            if self.hardening:
                # Only with the option, so the default test's frames stay bit for bit as they were.
                e_el = self.YIELD_STRAIN * (1.0 + self.hardening * progress)
            if self.upper_yield:
                e_el *= 1.0 + self.upper_yield * max(0.0, 1.0 - progress / self.UPPER_YIELD_DROP)
            e_pl = self.plastic_strain * (tau - self.TAU_YIELD) / (self.TAU_NECK - self.TAU_YIELD)
            e_n = 0.0
            phase = "plastic"
        else:
            s = (tau - self.TAU_NECK) / (1.0 - self.TAU_NECK)
            e_el = self.YIELD_STRAIN * (1.0 - self.UNLOAD * s)
            if self.hardening:
                e_el = self.YIELD_STRAIN * (1.0 + self.hardening) * (1.0 - self.UNLOAD * s)
            e_pl = self.plastic_strain
            e_n = self.neck_strain * s * s
            phase = "necking"
        u_r = self.DRIFT_PX[0] * tau + self._jitter[i, 0]
        v_r = self.DRIFT_PX[1] * tau + self._jitter[i, 1]
        st = {"frame": int(i), "tau": tau, "phase": phase, "e_el": e_el, "e_pl": e_pl, "e_neck": e_n,
              "u_rigid": u_r, "v_rigid": v_r, "shear_top": self.SHEAR_PX * tau, "gap": 0.0}
        if self.view == "centre":
            # The camera follows the stretch of the loading (frozen from the fracture on).
            st["v_rigid"] = v_r - 0.5 * (self._axial(st, self.gauge_top) + self._axial(st, self.gauge_bottom))
        if self.fractured(i):
            # The load drops to zero: both halves unload elastically; the crack opens.
            st.update(phase="fractured", e_el=0.0,
                      gap=self.GAP_START_PX + self.GAP_RATE_PX * (i - cast(int, self.fracture_frame)))
        return st

    # -- force (docs/guide/sources.md, Force) ------------------------------------------
    @property
    def area_mm2(self) -> float:
        """A0: the gauge section's initial cross-section, gauge width (px) / scale (px/mm) x thickness (mm)."""
        return 2.0 * self.gauge_half / self.scale_px_per_mm * self.thickness_mm

    def stress_mpa(self, i: int) -> float:
        """Engineering stress of the gauge section in frame ``i`` (MPa): E x e_el, 0 once broken."""
        return self.modulus_gpa * 1e3 * self.state(i)["e_el"]

    def force_n(self, i: int) -> float:
        """Force on the coupon in frame ``i`` (N): stress x A0; 0 from the fracture frame on."""
        return self.stress_mpa(i) * self.area_mm2

    @property
    def specimen(self) -> dict[str, Any]:
        """The coupon and its exact material law (dict; docs/guide/sources.md, Force).

        ``A0_mm2``, ``gauge_width_px``, ``thickness_mm``, ``scale_px_per_mm``, ``E_GPa``,
        ``hardening``, ``yield_MPa`` (E x 0.004), ``Rm_MPa`` (the largest engineering stress:
        yield x (1 + hardening), reached when the neck starts), ``Rp02_MPa`` (stress at 0.2 %
        uniform plastic strain; None when hardening > 0 and the uniform strain stays below 0.2 %)
        ``yield_strain`` and ``ReH_MPa`` (the upper yield strength, yield x (1 + upper_yield); with
        ``upper_yield`` it can exceed ``Rm_MPa``, which stays the largest stress after work
        hardening begins, as ISO 6892-1 3.9.2 reads Fm).
        """
        sigma_y = self.modulus_gpa * 1e3 * self.YIELD_STRAIN
        if not self.hardening:
            rp02 = sigma_y
        elif self.plastic_strain >= 0.002:
            rp02 = sigma_y * (1.0 + self.hardening * 0.002 / self.plastic_strain)
        else:
            rp02 = None
        return {"A0_mm2": self.area_mm2, "gauge_width_px": 2.0 * self.gauge_half, "thickness_mm": self.thickness_mm,
                "scale_px_per_mm": self.scale_px_per_mm, "E_GPa": self.modulus_gpa, "hardening": self.hardening,
                "yield_strain": self.YIELD_STRAIN, "yield_MPa": sigma_y, "Rp02_MPa": rp02,
                "ReH_MPa": sigma_y * (1.0 + self.upper_yield),
                "Rm_MPa": sigma_y * (1.0 + self.hardening)}

    # -- 1-D profiles -----------------------------------------------------
    def _box(self, Y):
        d = self.box_edge
        return 0.5 * (np.tanh((Y - self.gauge_top) / d) - np.tanh((Y - self.gauge_bottom) / d))

    def _box_integral(self, Y):
        d = self.box_edge
        return 0.5 * d * (_logcosh((Y - self.gauge_top) / d) - _logcosh((Y - self.gauge_bottom) / d))

    def half_width(self, Y: np.ndarray | float) -> np.ndarray:
        """Half-width of the undeformed coupon at reference row Y (px)."""
        f = self.fillet
        shoulder = 1.0 + 0.5 * (np.tanh((self.gauge_top - Y) / f) + np.tanh((Y - self.gauge_bottom) / f))
        return self.gauge_half + (self.shoulder_half - self.gauge_half) * shoulder

    def strain_yy(self, i: int, Y: npt.ArrayLike) -> np.ndarray:
        """Exact axial engineering strain dV/dY at reference rows Y for frame ``i`` (away from a crack)."""
        st = self.state(i)
        Y = np.asarray(Y, dtype=np.float64)
        a = self.area_ratio
        g = self._box(Y)
        return (st["e_el"] * (a + (1.0 - a) * g) + st["e_pl"] * g
                + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width))

    def plastic_strain_yy(self, i: int, Y: npt.ArrayLike) -> np.ndarray:
        """The plastic part of the axial strain at reference rows Y for frame ``i`` (never decreases)."""
        st = self.state(i)
        Y = np.asarray(Y, dtype=np.float64)
        return st["e_pl"] * self._box(Y) + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)

    def _antiderivative(self, st, Y):
        a = self.area_ratio
        G = self._box_integral(Y)
        s = self.neck_width
        return (st["e_el"] * (a * Y + (1.0 - a) * G) + st["e_pl"] * G
                + st["e_neck"] * s * np.tanh((Y - self.y_neck) / s))

    def _lateral(self, st, Y):
        """L(Y): lateral contraction factor, dU/dX = -L (the width's stretch is 1 - L)."""
        a = self.area_ratio
        g = self._box(Y)
        if self.lateral == "linear":
            return (self.NU_ELASTIC * st["e_el"] * (a + (1.0 - a) * g)
                    + self.NU_PLASTIC * (st["e_pl"] * g
                                         + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)))
        elastic = self.NU_ELASTIC * st["e_el"] * (a + (1.0 - a) * g)
        plastic = st["e_pl"] * g + st["e_neck"] * _sech2((Y - self.y_neck) / self.neck_width)
        return 1.0 - (1.0 - elastic) / np.sqrt(1.0 + plastic)

    def _axial(self, st, Y):
        """V(Y) without rigid motion: minus the stretch of the material between Y and the grip."""
        return -(self._antiderivative(st, self.y_grip) - self._antiderivative(st, Y))

    def _shear(self, st, Y):
        return st["shear_top"] * (self.y_grip - Y) / self.y_grip

    def displacement(self, i: int, X: npt.ArrayLike, Y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Exact (U, V) of reference points (X, Y) in frame ``i`` (float64 arrays, broadcast).

        Once broken, points with Y < ``y_neck`` belong to the upper half (moved away by the gap).
        """
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64))
        st = self.state(i)
        U = st["u_rigid"] + self._shear(st, Y) - self._lateral(st, Y) * (X - self.x_centre)
        V = st["v_rigid"] + self._axial(st, Y)
        if st["gap"]:
            V = V - st["gap"] * (Y < self.y_neck)
        return U, V

    def crack_faces(self, i: int) -> tuple[float, float] | None:
        """Deformed rows (upper face, lower face) of the crack in frame ``i``; None before the fracture."""
        st = self.state(i)
        if not st["gap"]:
            return None
        lower = self.y_neck + st["v_rigid"] + float(self._axial(st, self.y_neck))
        return lower - st["gap"], lower

    def row_cover(self, i: int, rows: npt.ArrayLike) -> np.ndarray:
        """Fraction of each deformed row's pixel covered by material along y: 1, or less at and in the crack."""
        y = np.asarray(rows, dtype=np.float64)
        faces = self.crack_faces(i)
        if faces is None:
            return np.ones(y.shape)
        upper, lower = faces
        below = np.clip(y + 0.5 - lower, 0.0, 1.0)
        above = np.clip(upper - (y - 0.5), 0.0, 1.0)
        return np.maximum(below, above)

    def _crack_shift(self, st, y):
        """Shift of deformed rows into the lower half's map: the gap for rows of the upper half, else 0."""
        upper = self.y_neck + st["v_rigid"] + float(self._axial(st, self.y_neck)) - st["gap"]
        return st["gap"] * (y < upper + 0.5 * st["gap"])

    def inverse_rows(self, i: int, rows: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For deformed rows y: the reference row Y and the column map X = alpha + beta * x.

        Solves ``y = Y + V(Y)`` by safeguarded Newton (a bracket kept from f' >= 1, bisection when a
        step leaves it) to 1e-12 px, then inverts the row's affine column map ``x = X + U(X, Y)``.
        Once broken, rows above the middle of the crack are mapped through the upper half, the others
        through the lower one (the rows in the crack get ``row_cover`` 0).
        """
        st = self.state(i)
        y = np.asarray(rows, dtype=np.float64)
        if st["gap"]:
            y = y + self._crack_shift(st, y)     # the upper half is the lower half's map shifted by the gap
        Y = y - st["v_rigid"] - self._axial(st, y)   # fixed-point start
        low = np.full(Y.shape, -np.inf)
        high = np.full(Y.shape, np.inf)
        previous = np.full(Y.shape, np.inf)
        for _ in range(100):
            residual = Y + st["v_rigid"] + self._axial(st, Y) - y
            slope = 1.0 + self.strain_yy(i, Y)
            size = np.abs(residual)
            # f(Y) = Y + V(Y) - y has f' = 1 + e_yy >= 1, so the root lies within |f(Y)| of Y.
            high = np.where(residual > 0.0, np.minimum(high, Y), np.minimum(high, Y - residual))
            low = np.where(residual > 0.0, np.maximum(low, Y - residual), np.maximum(low, Y))
            step = Y - residual / slope
            # Bisect where Newton leaves the bracket or fails to halve the residual (a cycle, at very large
            # strain); never near the root, where rounding sets the residual and Newton's step is kept.
            bisect = ((step <= low) | (step >= high) | (size > 0.5 * previous)) & (size > 1e-9)
            Y = np.where(bisect, 0.5 * (low + high), step)
            previous = size
            if np.max(size) < 1e-12:
                break
        else:
            residual = Y + st["v_rigid"] + self._axial(st, Y) - y
            if np.max(np.abs(residual)) > 1e-9 * max(1.0, float(np.max(np.abs(y)))):  # pragma: no cover
                raise SourceError("tensile model: could not invert the axial displacement")
        L = self._lateral(st, Y)
        offset = st["u_rigid"] + self._shear(st, Y)
        # x = X + offset - L (X - xc)  ->  X = xc + (x - offset - xc) / (1 - L)
        beta = 1.0 / (1.0 - L)
        alpha = self.x_centre - (offset + self.x_centre) * beta
        return Y, alpha, beta

    def nominal_strain(self, i: int) -> float:
        """Mean axial strain over the gauge section (what an extensometer would read; with the crack's gap)."""
        st = self.state(i)
        top, bottom = self.gauge_top, self.gauge_bottom
        return float((self._antiderivative(st, bottom) - self._antiderivative(st, top) + st["gap"])
                     / (bottom - top))

    def visible(self, i: int, X: npt.ArrayLike, Y: npt.ArrayLike, half_width: float = 0.0) -> np.ndarray:
        """Whether the square subset of half-width ``half_width`` around each reference point (X, Y) is fully seen.

        True where the subset is all specimen (inside the coupon's outline), on one side of the crack
        (from the fracture on: Y - d >= ``y_neck`` or Y + d < ``y_neck``) and, in the reference and in
        frame ``i``, inside the image (pixel centres 0..W-1, 0..H-1).
        """
        X, Y = np.broadcast_arrays(np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64))
        d = float(half_width)
        H, W = self.shape
        edge = np.minimum(np.minimum(self.half_width(Y - d), self.half_width(Y)), self.half_width(Y + d))
        seen = np.abs(X - self.x_centre) + d <= edge
        if self.fractured(i):
            seen &= (Y - d >= self.y_neck) | (Y + d < self.y_neck)
        for frame in (0, i):
            # U is affine in X on a row and V depends on Y alone: the corners bound the deformed subset.
            for dy in (-d, d):
                for dx in (-d, d):
                    u, v = self.displacement(frame, X + dx, Y + dy)
                    x, y = X + dx + u, Y + dy + v
                    seen &= (x >= 0.0) & (x <= W - 1.0) & (y >= 0.0) & (y <= H - 1.0)
        return seen


class FrameTruth:
    """Exact displacement of reference points in one frame: ``truth(x, y) -> (u, v)`` arrays.

    ``truth.visible(x, y, half_width)`` says which reference points' subsets are fully seen in
    that frame (the source's ``visible``; all of them when the source gives none).
    """

    def __init__(self, function: Callable[[int, npt.ArrayLike, npt.ArrayLike], tuple[np.ndarray, np.ndarray]],
                 frame_index: int, description: str,
                 visible: Callable[[int, npt.ArrayLike, npt.ArrayLike, float], np.ndarray] | None = None) -> None:
        self._function = function
        self._visible = visible
        self.frame_index = int(frame_index)
        self.description = description

    def __call__(self, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        return self._function(self.frame_index, x, y)

    def visible(self, x: npt.ArrayLike, y: npt.ArrayLike, half_width: float = 0.0) -> np.ndarray:
        """Boolean array: the subset of half-width ``half_width`` px around each reference point is fully seen."""
        if self._visible is None:
            return np.ones(np.broadcast(np.asarray(x), np.asarray(y)).shape, dtype=bool)
        return self._visible(self.frame_index, x, y, half_width)

    def __repr__(self) -> str:
        return f"FrameTruth({self.description}, frame={self.frame_index})"
