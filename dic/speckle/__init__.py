"""Exact simulated speckle images (Zhou & Goodson 2001).

The reference image is a sum of Gaussian spots with i.i.d. uniform centres ``(x_k, y_k)``::

    I(X, Y) = sum_k I0 * exp(-((X - x_k)**2 + (Y - y_k)**2) / R**2)

evaluated analytically at pixel centres (``x`` = column, ``y`` = row). A deformed image is
the same function at the inverse-mapped coordinates: with the Lagrangian convention "content
at (X, Y) in the reference appears at (X + U(X, Y), Y + V(X, Y))", pixel (x, y) of the
deformed image is ``I(X, Y)`` where ``x = X + U(X, Y)``, ``y = Y + V(X, Y)``, solved per pixel
to 1e-10 px, so deformed images are exact for any invertible field: no image is ever
interpolated.

Guarantees: ``radius`` is R above (the 1/e half-width of a spot); ``n_speckles`` (or
``density``) speckles are centred in the image's footprint, with the same density in a
``margin`` around it; spots are truncated at ``cutoff * R``; every integer image of one
pattern uses one grey-scale factor (the brightest reference pixel at ``fill`` of full
scale); ``pixel_integration=True`` averages over each pixel's area; results do not depend on
the number of threads.

Why each choice, the accuracy of the quadrature and the kernels: docs/guide/sources.md ("The
speckle images"); design notes: algorithms.md section 8.
"""

from livedic.dic.speckle.fields import DisplacementField, affine, sinusoid, translation
from livedic.dic.speckle.intensity import GAUSS_LEGENDRE_ORDER, INVERSE_TOLERANCE
from livedic.dic.speckle.pattern import DEFAULT_CUTOFF, DEFAULT_FILL, SpecklePattern
from livedic.dic.speckle.render import render

__all__ = ["DEFAULT_CUTOFF", "DEFAULT_FILL", "GAUSS_LEGENDRE_ORDER", "INVERSE_TOLERANCE", "DisplacementField",
           "translation", "affine", "sinusoid", "SpecklePattern", "render"]
