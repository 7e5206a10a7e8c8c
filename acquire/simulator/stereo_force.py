"""The stereo test's force: what the simulated testing machine measures on the stereo coupon.

The stereo coupon's motion is prescribed (coupon3d: a uniform axial strain ``e`` growing linearly to ``strain=``,
a neck, a turn and a translation); it has no material of its own. Its force is that of a steel-like law applied to
the uniform part's engineering strain ``e`` on the coupon's cross-section A0 = width x thickness: elastic with the
tensile simulator's E (200 GPa) up to its yield strain (0.4 %, 800 MPa), then linear work hardening of plastic
modulus ``PLASTIC_MODULUS_GPA`` (stress 800 MPa + K e_p, e = stress / E + e_p)::

    F = A0 stress(e)

The hardening makes the yielding continuous, so a report reads E and Rp0.2 (820 MPa, once the test passes 0.2 %
plastic strain) from it; a perfectly plastic law's flat top, shorter than the 0.5 % plateau ISO 6892-1 reading needs
at the default 1 % strain, gave neither. The test ends before any maximum of the material's force (the law has no
neck): the largest force is the last frame's, so a report gives no Rm, Ag or Agt (the test ended before Fm). The
neck's extra strain is local (the force is the uniform part's); it grows from the first frame, which a real neck
does not (it starts at maximum force), so an extensometer across it reads more strain than ``e`` and the curve it
gives follows the law only with ``neck=0``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion
from livedic.acquire.simulator.model import TensileModel
from livedic.acquire.simulator.options import DEFAULT_MODULUS_GPA

# The law's plastic modulus K (GPa): stress = yield + K e_p after yielding (5 % of E: clearly continuous yielding).
PLASTIC_MODULUS_GPA = 10.0
# The law's proof strain: Rp0.2 is the stress at 0.2 % plastic strain.
PROOF_STRAIN = 0.002


def stress_mpa(e: float) -> float:
    """The law's engineering stress (MPa) at engineering strain ``e``: E e, then yield + K e_p."""
    modulus = DEFAULT_MODULUS_GPA * 1e3
    yield_strain = TensileModel.YIELD_STRAIN
    if e <= yield_strain:
        return modulus * float(e)
    plastic = (float(e) - yield_strain) / (1.0 + PLASTIC_MODULUS_GPA / DEFAULT_MODULUS_GPA)
    return modulus * yield_strain + PLASTIC_MODULUS_GPA * 1e3 * plastic


def plastic_strain(e: float) -> float:
    """The law's plastic strain at engineering strain ``e`` (0 while elastic)."""
    return max(0.0, float(e) - stress_mpa(e) / (DEFAULT_MODULUS_GPA * 1e3))


def area_mm2(coupon: Coupon) -> float:
    """A0: the coupon's initial cross-section, width x thickness (mm^2)."""
    return coupon.width_mm * coupon.thickness_mm


def _force_n(coupon: Coupon, motion: CouponMotion, frame: int) -> float:
    """The force (N) on the coupon in test frame ``frame``: the law's stress at its uniform strain, times A0."""
    return stress_mpa(motion.state(frame).e) * area_mm2(coupon)


def specimen(coupon: Coupon, motion: CouponMotion) -> dict[str, Any]:
    """The coupon and its law, as ``TensileModel.specimen`` gives the tensile test's (dict).

    ``A0_mm2``, ``width_mm``, ``thickness_mm``, ``E_GPa``, ``plastic_modulus_GPa``, ``yield_strain``,
    ``yield_MPa``, ``Rp02_MPa`` (None when the test ends before 0.2 % plastic strain), ``Rm_MPa`` (the largest
    stress of the test: its last frame's, before the material's own maximum), ``law``.
    """
    sigma_y = stress_mpa(TensileModel.YIELD_STRAIN)
    reaches_proof = plastic_strain(motion.strain) >= PROOF_STRAIN
    return {"A0_mm2": area_mm2(coupon), "width_mm": coupon.width_mm, "thickness_mm": coupon.thickness_mm,
            "E_GPa": DEFAULT_MODULUS_GPA, "plastic_modulus_GPa": PLASTIC_MODULUS_GPA,
            "yield_strain": TensileModel.YIELD_STRAIN, "yield_MPa": sigma_y,
            "Rp02_MPa": sigma_y + PLASTIC_MODULUS_GPA * 1e3 * PROOF_STRAIN if reaches_proof else None,
            "Rm_MPa": stress_mpa(motion.strain),
            "law": "elastic, then linear work hardening, on the uniform axial strain"}


def forces_n(coupon: Coupon, motion: CouponMotion, frames: list[int]) -> np.ndarray:
    """The force (N) of each test frame in ``frames`` (float64 array)."""
    return np.array([_force_n(coupon, motion, frame) for frame in frames], dtype=np.float64)
