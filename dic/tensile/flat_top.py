"""Where Ag and Agt are read: at maximum force, or at the middle of a plateau at maximum force.

ISO 6892-1 reads the percentage plastic (Ag) and total (Agt) extension at maximum force Fm. On a
force-extension curve with a flat top (materials with little work hardening hold the maximum force
over an extension) the frame of the largest reading is decided by the force's noise, not by the
material; the standard then reads the extension at the middle of the plateau (the wording was not at
hand here: see docs/guide/tensile-test.md, "Ag on a flat top", for what was read and what was not).

The plateau is the contiguous stretch of frames around the maximum of the running-mean stress
(``yielding.smooth``, ``SMOOTH_FRAMES``) whose running mean stays within a tolerance of that maximum:
``FLAT_TOP_TOLERANCE`` of Rm, widened to ``NOISE_SIGMAS`` standard deviations of one reading when
the measured force is noisier (``yielding.stress_noise``: 0.5 % of Rm with a class 0.5 load cell's
0.1 % noise). It is a real plateau when it covers at least ``MIN_FLAT_TOP_EXTENSION`` (1 %) of
strain; a narrower stretch is the rounding of an ordinary maximum, and Ag stays at the frame of Rm.
A top that stays within the tolerance over 1 % is a plateau whatever its exact shape (a gently
rounded one too): the force does not resolve where along it the maximum lies, so its middle is read.
Limit: with noisier force (class 1, ~0.3 %) the widened stretch of a sharp peak reaches 1 % and is
read as a plateau (77 of 100 seeds on the tests' curve); its middle still lies within 0.2 %pt of the peak.

Data only: a ``FlatTop`` names the rule used (``AgRule``), the plateau's frames and strains and the
strain Ag is read at.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from livedic.dic.tensile.yielding import NOISE_SIGMAS, SMOOTH_FRAMES, smooth, stress_noise

# Share of Rm within which the running mean is "at maximum force" on a noise-free curve: forces this close
# are one force to a class 0.5 load cell (ISO 7500-1), which reads with ~0.1 % noise and may be off in
# indication by more. A noisier curve widens it (see flat_top).
FLAT_TOP_TOLERANCE = 0.002
# Shortest plateau (strain) read as a flat top. A sharp maximum's stretch within the tolerance is the
# tolerance over the slopes either side: ~0.2 % of strain noise-free, ~0.55 % with a class 0.5 load cell's
# noise, on a curve hardening at 1 GPa and necking at 0.7 GPa; twice that is no rounding of a peak.
MIN_FLAT_TOP_EXTENSION = 0.01

_NAN = float("nan")


class AgRule(enum.Enum):
    """Where Ag and Agt are read."""
    AT_MAXIMUM = "at maximum force: the frame of Rm"
    PLATEAU_MIDDLE = "at the middle of the plateau at maximum force (ISO 6892-1's rule for a flat top)"


@dataclass(frozen=True)
class FlatTop:
    """The top of the curve as Ag reads it.

    Attributes
    ----------
    rule : AgRule
    strain : float
        The strain Ag and Agt are read at: the middle of the plateau, or the strain at Rm.
    frames : (int, int)
        First and last frame of the stretch within the tolerance of the maximum (input indices).
    strains : (float, float)
        Their strains.
    tolerance_MPa : float
        The stress tolerance used.
    """
    rule: AgRule
    strain: float
    frames: tuple = (-1, -1)
    strains: tuple = (_NAN, _NAN)
    tolerance_MPa: float = _NAN

    def describe(self) -> str:
        """One line for the method text: the rule and, on a plateau, its strains."""
        if self.rule is AgRule.PLATEAU_MIDDLE:
            return (f"{self.rule.value}: the running-mean stress stays within {self.tolerance_MPa:.3g} MPa of its "
                    f"maximum from {100 * self.strains[0]:.3f} % to {100 * self.strains[1]:.3f} % strain")
        return self.rule.value


def flat_top(strain: np.ndarray, stress: np.ndarray, frames: np.ndarray, rm_frame: int, rm_strain: float) -> FlatTop:
    """Whether the curve has a plateau at maximum force, and the strain Ag is read at.

    Parameters
    ----------
    strain, stress : ndarray (n,)
        Engineering strain (-) and stress (MPa) per frame.
    frames : ndarray of int
        The frames searched (finite strain and stress, from the start of work hardening on), in order.
    rm_frame : int
        The frame of Rm (input index; a member of ``frames``).
    rm_strain : float
        The strain there.

    Returns
    -------
    FlatTop
        ``PLATEAU_MIDDLE`` with the middle of the plateau's strains when the stretch around the maximum
        within the tolerance covers at least ``MIN_FLAT_TOP_EXTENSION``; else ``AT_MAXIMUM`` at Rm.
    """
    at_maximum = FlatTop(AgRule.AT_MAXIMUM, float(rm_strain))
    if frames.size < SMOOTH_FRAMES:
        return at_maximum
    s = smooth(stress[frames])
    e = strain[frames]
    peak = int(np.argmax(s))
    # The running mean's maximum lies ~2.5 of its SDs above a noisy plateau and its lowest frames as far below:
    # NOISE_SIGMAS SDs of one reading (~11 of the mean's) keep the plateau in one piece.
    tolerance = max(FLAT_TOP_TOLERANCE * s[peak], NOISE_SIGMAS * stress_noise(stress[frames]))
    below = s < s[peak] - tolerance
    before = np.flatnonzero(below[:peak])
    after = np.flatnonzero(below[peak:])
    first = int(before[-1]) + 1 if before.size else 0
    last = peak + int(after[0]) - 1 if after.size else s.size - 1
    extent = e[first:last + 1]
    start, end = float(extent.min()), float(extent.max())
    span = (int(frames[first]), int(frames[last]))
    if end - start < MIN_FLAT_TOP_EXTENSION:
        return FlatTop(AgRule.AT_MAXIMUM, float(rm_strain), span, (start, end), float(tolerance))
    return FlatTop(AgRule.PLATEAU_MIDDLE, 0.5 * (start + end), span, (start, end), float(tolerance))
