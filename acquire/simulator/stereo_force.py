"""The stereo test's force: what the simulated testing machine measures on the stereo coupon.

The stereo coupon's motion is prescribed (coupon3d: a uniform axial strain ``e`` growing linearly to ``strain=``,
a neck, a turn and a translation); it has no material of its own. Its force is that of the tensile simulator's
default law (acquire.simulator.model): a steel-like elastic, perfectly plastic material, E 200 GPa and yield at
0.4 % strain (800 MPa), applied to the uniform part's engineering strain ``e`` on the coupon's cross-section
A0 = width x thickness::

    F = A0 E min(e, e_yield)

The neck's extra strain is local (the force is the uniform part's); it grows from the first frame, which a real
neck does not (it starts at maximum force), so an extensometer across it reads more strain than ``e`` and the
curve it gives follows the law only with ``neck=0``. With no work hardening there is no maximum force after
yielding (ISO 6892-1 3.9.2 Note 1): a report gives E and Rp0.2 (when ``strain`` passes 0.6 %), Rm with its reason.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion
from livedic.acquire.simulator.model import TensileModel
from livedic.acquire.simulator.options import DEFAULT_MODULUS_GPA

# The law's proof strain: Rp0.2 is the stress at 0.2 % plastic strain.
PROOF_STRAIN = 0.002


def stress_mpa(e: float) -> float:
    """The law's engineering stress (MPa) at engineering strain ``e``: E min(e, e_yield)."""
    return DEFAULT_MODULUS_GPA * 1e3 * min(float(e), TensileModel.YIELD_STRAIN)


def area_mm2(coupon: Coupon) -> float:
    """A0: the coupon's initial cross-section, width x thickness (mm^2)."""
    return coupon.width_mm * coupon.thickness_mm


def _force_n(coupon: Coupon, motion: CouponMotion, frame: int) -> float:
    """The force (N) on the coupon in test frame ``frame``: the law's stress at its uniform strain, times A0."""
    return stress_mpa(motion.state(frame).e) * area_mm2(coupon)


def specimen(coupon: Coupon, motion: CouponMotion) -> dict[str, Any]:
    """The coupon and its law, as ``TensileModel.specimen`` gives the tensile test's (dict).

    ``A0_mm2``, ``width_mm``, ``thickness_mm``, ``E_GPa``, ``hardening`` (0), ``yield_strain``, ``yield_MPa``,
    ``Rp02_MPa`` (the yield stress; None when the test's strain stays below yield + 0.2 %), ``Rm_MPa`` (the
    largest stress, the yield stress: with no work hardening ISO 6892-1 leaves Fm undefined), ``law``.
    """
    sigma_y = stress_mpa(TensileModel.YIELD_STRAIN)
    reaches_proof = motion.strain >= TensileModel.YIELD_STRAIN + PROOF_STRAIN
    return {"A0_mm2": area_mm2(coupon), "width_mm": coupon.width_mm, "thickness_mm": coupon.thickness_mm,
            "E_GPa": DEFAULT_MODULUS_GPA, "hardening": 0.0, "yield_strain": TensileModel.YIELD_STRAIN,
            "yield_MPa": sigma_y, "Rp02_MPa": sigma_y if reaches_proof else None, "Rm_MPa": sigma_y,
            "law": "elastic, perfectly plastic, on the uniform axial strain"}


def forces_n(coupon: Coupon, motion: CouponMotion, frames: list[int]) -> np.ndarray:
    """The force (N) of each test frame in ``frames`` (float64 array)."""
    return np.array([_force_n(coupon, motion, frame) for frame in frames], dtype=np.float64)
