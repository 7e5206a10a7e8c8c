"""The grey-level interpolant IC-GN samples the deformed image with: ``bspline3`` (bicubic B-spline, the library's
default and ``livedic run``'s), ``bspline5`` (biquintic) or ``bspline7`` (biseptic B-spline; ``livedic measure``'s
default with icgn: ``stream.session.config.measure_defaults``).

``Interpolation.parse`` reads the one textual form and is the only place it is checked; ``degree`` is what
``dic.bspline.prefilter`` and ``dic.subpixel.icgn.prepare_target`` take. The quintic reproduces polynomials up
to degree 5 and cuts the sub-pixel interpolation bias (40x on smooth rendered speckle, about 2x on DIC Challenge
1.0 Sample 3, whose content near the Nyquist frequency no B-spline follows: docs/guide/measure.md; Ncorr's
choice) for ~2x the kernel's taps (36 instead of 16 per sample). The septic (64 taps) lowers Sample 3's bias and
SD further (0.0014 px with no pre-filter), enough to meet issue 23's 0.001 px with a lighter pre-filter.
"""

from __future__ import annotations

from dataclasses import dataclass

BSPLINE3 = "bspline3"
BSPLINE5 = "bspline5"
BSPLINE7 = "bspline7"
DEFAULT_INTERPOLATION = BSPLINE3
# name -> (B-spline degree, how a report names it)
_KINDS = {BSPLINE3: (3, "bicubic B-spline (Unser's prefilter, dic.bspline)"),
          BSPLINE5: (5, "biquintic B-spline (Unser's prefilter, dic.bspline)"),
          BSPLINE7: (7, "biseptic B-spline (Unser's prefilter, dic.bspline)")}
INTERPOLATIONS: tuple[str, ...] = tuple(_KINDS)


@dataclass(frozen=True)
class Interpolation:
    """A B-spline interpolant by name (``str(interpolation)``: "bspline3", "bspline5" or "bspline7", as recorded)."""
    name: str = DEFAULT_INTERPOLATION

    def __post_init__(self) -> None:
        if self.name not in _KINDS:
            raise ValueError(f"unknown interpolation {self.name!r}: choose one of {', '.join(INTERPOLATIONS)}")

    @classmethod
    def parse(cls, text: str | Interpolation | None) -> Interpolation:
        """``"bspline3"`` (or None), ``"bspline5"`` or ``"bspline7"``, any case; ValueError (one line) for anything
        else.

        Examples
        --------
        >>> Interpolation.parse("BSpline5").degree
        5
        """
        if isinstance(text, Interpolation):
            return text
        if text is None:
            return cls()
        return cls(str(text).strip().lower())

    def __str__(self) -> str:
        return self.name

    @property
    def degree(self) -> int:
        """Of the B-spline (``dic.bspline.DEGREES``)."""
        return _KINDS[self.name][0]

    def describe(self) -> str:
        """For people (a report's analysis table)."""
        return _KINDS[self.name][1]
