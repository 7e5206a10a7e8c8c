"""Every sub-pixel method behind one interface: what ``dic.measure`` and the trackers ask of a method.

A ``SubpixelMethod`` holds a method's traits (the margin its interpolation needs, the shape function it
refines, whether it runs on prepared reference data, takes a seed, carries terms from frame to frame) and
the calls that differ (refine, refine_prepared, extending the first-order reference data). Callers look a
method up in ``METHODS`` by the name a user gives and then ask it, never compare its name. The methods
themselves are one module each in this package; docs/guide/measure.md compares them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from livedic.dic.bspline import INTERPOLATION_MARGIN
from livedic.dic.interpolation import BSPLINE3, BSPLINE5, BSPLINE7, DEFAULT_INTERPOLATION, Interpolation
from livedic.dic.subpixel import gradient_method, icgn, icgn2, improved_surface_fit, newton_raphson, surface_fit

BSPLINE = Interpolation(BSPLINE3).describe()


@dataclass(frozen=True)
class SubpixelMethod:
    """A sub-pixel method as measure and tracking use it.

    Attributes
    ----------
    name : str
        The name users give (``--subpixel``).
    module : module or None
        Its module, whose ``refine`` follows the ``dic.measure`` contract; None: no refinement (the integer
        search's result is kept).
    margin : int
        Pixels its interpolation or fit needs beyond the subset.
    shape_order : int
        The shape function it refines to by default: 0 a shift around an integer peak (the peak fits),
        1 affine (it estimates displacement gradients), 2 quadratic.
    prepared : bool
        IC-GN: its reference data are prepared once (``icgn.prepare_reference``) and each target refined
        from them (``refine_prepared``); the texture gates read the same data.
    seeded : bool
        It runs a stochastic optimiser and takes the seed.
    final_after_guidance : bool
        The reliability-guided propagation (first-order IC-GN) already is this method's result.
    shape_terms : tuple of str
        Start terms it carries from frame to frame beyond u, v and the gradients.
    reference_options : tuple of str
        Its options that shape the prepared reference data (set once), not each refinement.
    shape_function, interpolant, criterion : str
        How a report names its subset shape function, the grey-level interpolation it samples the deformed
        image with (by default: ``interpolant_for`` names the one chosen), and the similarity it optimises
        (the iDICs guide's analysis-parameter table).
    interpolations : tuple of str
        The B-spline interpolants (``dic.interpolation``) it can sample the deformed image with; empty for
        methods that interpolate no B-spline (the default name is accepted by every method: it changes nothing).
    """
    name: str
    module: ModuleType | None
    margin: int
    shape_order: int = 0
    prepared: bool = False
    seeded: bool = False
    final_after_guidance: bool = False
    shape_terms: tuple[str, ...] = ()
    reference_options: tuple[str, ...] = ()
    shape_function: str = "zero order (rigid shift)"
    interpolant: str = "none (integer pixels)"
    criterion: str = "ZNCC"
    interpolations: tuple[str, ...] = ()

    def __reduce__(self):
        # a tracker sent to another process (replay --workers) carries its method by name, not its module
        return subpixel_method, (self.name,)

    @property
    def refines(self) -> bool:
        """It refines to sub-pixel values (``"none"`` keeps the integer search's)."""
        return self.module is not None

    @property
    def first_order(self) -> bool:
        """It estimates displacement gradients (and fits a shift where the texture cannot pin an affine warp);
        the others work around an integer peak, so a float start is rounded for them."""
        return self.shape_order >= 1

    def checked_interpolation(self, interpolation: str | Interpolation | None) -> Interpolation:
        """``interpolation`` parsed; ValueError (one line) when it is not the default and this method cannot
        sample with it."""
        chosen = Interpolation.parse(interpolation)
        if chosen.name != DEFAULT_INTERPOLATION and chosen.name not in self.interpolations:
            able = ", ".join(name for name, method in METHODS.items() if chosen.name in method.interpolations)
            raise ValueError(f"--interpolation {chosen} is not available with --subpixel {self.name}: "
                             f"use it with {able}, or --interpolation {DEFAULT_INTERPOLATION}")
        return chosen

    def interpolant_for(self, interpolation: str | Interpolation | None) -> str:
        """How a report names the interpolant this method sampled with, ``interpolation`` chosen."""
        if not self.interpolations:
            return self.interpolant
        return Interpolation.parse(interpolation).describe()

    def pop_reference_options(self, options: dict[str, Any]) -> dict[str, Any]:
        """The options of ``options`` that shape the reference data (``reference_options``), taken out of it."""
        return {name: options.pop(name) for name in self.reference_options if name in options}

    def reference_data(self, first: icgn.IcgnReference, **reference_options: Any) -> Any:
        """The prepared reference data this method refines from, given the first-order ones."""
        return first

    def first_order_data(self, prepared: Any) -> icgn.IcgnReference:
        """The first-order IC-GN part of ``prepared`` (what the guided propagation and re-finds run on)."""
        return prepared

    def moved_data(self, prepared: Any, dx: int, dy: int, shape: tuple[int, int]) -> Any:
        """``prepared`` on a window of ``shape`` whose origin lies (dx, dy) px up and left of the one it was made on.

        Each point's data come from the pixels around it, so only the positions change; the caller checks that
        every subset sits the same way in both windows (inside, and clear of the gradient stencil's border).
        """
        return dataclasses.replace(prepared, xs=prepared.xs + dx, ys=prepared.ys + dy, shape=tuple(shape))

    def refine_prepared(self, prepared: Any, target: Any, u0: np.ndarray, v0: np.ndarray, **options: Any) -> Any:
        """``module.refine_prepared`` (prepared methods only)."""
        assert self.module is not None, f"{self.name} has no prepared refinement"
        return self.module.refine_prepared(prepared, target, u0, v0, **options)


@dataclass(frozen=True)
class _SecondOrderIcgn(SubpixelMethod):
    """icgn2: its 12-parameter reference data extend the first-order ones (``icgn2.prepare_from``)."""

    def reference_data(self, first, *, vif_max=icgn2.VIF2_MAX, curvature_threshold=None):
        return icgn2.prepare_from(first, vif_max=vif_max, curvature_threshold=curvature_threshold)

    def first_order_data(self, prepared):
        return prepared.first

    def moved_data(self, prepared, dx, dy, shape):
        return dataclasses.replace(prepared, first=super().moved_data(prepared.first, dx, dy, shape))


METHODS: dict[str, SubpixelMethod] = {method.name: method for method in (
    SubpixelMethod("none", None, 0, shape_function="zero order (integer shift)"),
    SubpixelMethod("surface-fit", surface_fit, 1, seeded=True,
                   interpolant="none: a quadratic surface fitted to the ZNCC around its integer peak"),
    SubpixelMethod("gradient", gradient_method, 2, interpolant="none: first-order Taylor expansion of the image",
                   criterion="SSD of the intensity-normalised subsets (linearised)"),
    SubpixelMethod("newton-raphson", newton_raphson, INTERPOLATION_MARGIN, shape_order=1,
                   shape_function="first order (affine, 6 parameters)", interpolant=BSPLINE,
                   criterion="ZNSSD (equivalent to ZNCC)", interpolations=(BSPLINE3,)),
    SubpixelMethod("improved-surface-fit", improved_surface_fit, 3, seeded=True,
                   interpolant="none: an improved surface fitted to the ZNCC around its integer peak"),
    SubpixelMethod("icgn", icgn, INTERPOLATION_MARGIN, shape_order=1, prepared=True, final_after_guidance=True,
                   shape_function="first order (affine, 6 parameters)", interpolant=BSPLINE,
                   criterion="ZNSSD (equivalent to ZNCC)", interpolations=(BSPLINE3, BSPLINE5, BSPLINE7)),
    _SecondOrderIcgn("icgn2", icgn2, INTERPOLATION_MARGIN, shape_order=2, prepared=True,
                     shape_terms=icgn2.SECOND_ORDER, reference_options=("vif_max", "curvature_threshold"),
                     shape_function="second order (quadratic, 12 parameters)", interpolant=BSPLINE,
                     criterion="ZNSSD (equivalent to ZNCC)", interpolations=(BSPLINE3,)),
)}
SUBPIXEL_METHODS: tuple[str, ...] = tuple(METHODS)


def subpixel_method(name: str) -> SubpixelMethod:
    """The method called ``name``; ValueError (one line) naming the choices for an unknown one."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown sub-pixel method {name!r}: choose one of {', '.join(SUBPIXEL_METHODS)}") from None
