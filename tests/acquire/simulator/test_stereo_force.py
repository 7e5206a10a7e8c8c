"""stereo_force: the stereo coupon's law, checked against its closed form (E, yield, linear hardening, Rp0.2)."""

import pytest

from livedic.acquire.simulator.options import DEFAULT_MODULUS_GPA
from livedic.acquire.simulator.stereo_force import PLASTIC_MODULUS_GPA, PROOF_STRAIN, plastic_strain, stress_mpa

E_MPA = DEFAULT_MODULUS_GPA * 1e3


def test_elastic_then_linear_hardening_continuous_at_yield():
    assert stress_mpa(0.0) == 0.0 and stress_mpa(0.002) == pytest.approx(E_MPA * 0.002, rel=1e-15)
    assert stress_mpa(0.004) == pytest.approx(800.0, rel=1e-15)                 # the yield point
    assert stress_mpa(0.004 + 1e-12) == pytest.approx(800.0, rel=1e-9)          # continuous there
    assert plastic_strain(0.003) == 0.0
    # past yield: e = stress / E + e_p and stress = 800 + K e_p
    for e in (0.005, 0.01, 0.05):
        s, ep = stress_mpa(e), plastic_strain(e)
        assert s == pytest.approx(800.0 + PLASTIC_MODULUS_GPA * 1e3 * ep, rel=1e-12)
        assert e == pytest.approx(s / E_MPA + ep, rel=1e-12)


def test_the_proof_strength_is_the_stress_at_the_proof_plastic_strain():
    rp = 800.0 + PLASTIC_MODULUS_GPA * 1e3 * PROOF_STRAIN                        # 820 MPa
    e = rp / E_MPA + PROOF_STRAIN
    assert stress_mpa(e) == pytest.approx(rp, rel=1e-12) and plastic_strain(e) == pytest.approx(PROOF_STRAIN, rel=1e-9)
