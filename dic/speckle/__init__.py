"""Exact simulated speckle images (Zhou & Goodson 2001).

Zhou P. and Goodson K. E., "Subpixel displacement and deformation gradient
measurement using digital image/speckle correlation (DISC)", Opt. Eng. 40(8),
1613-1620 (2001), DOI 10.1117/1.1387992. The reference image is a sum of
Gaussian spots with i.i.d. uniform centres ``(x_k, y_k)``::

    I(X, Y) = sum_k I0 * exp(-((X - x_k)**2 + (Y - y_k)**2) / R**2)

evaluated analytically at pixel centres (``x`` = column, ``y`` = row). A
deformed image is the same function evaluated at the inverse-mapped
coordinates: with the Lagrangian convention "content at (X, Y) in the reference
appears at (X + U(X, Y), Y + V(X, Y))", pixel (x, y) of the deformed image is
``g(x, y) = I(X, Y)`` where ``x = X + U(X, Y)``, ``y = Y + V(X, Y)``. That
equation is solved per pixel (closed form for translation and affine fields, a
1-D safeguarded Newton table for sinusoids, a vectorised numpy Newton iteration
to 1e-10 px for any other callable), so deformed images are exact for any
invertible field: no image is ever interpolated.

Choices made here (design notes: algorithms.md section 8):

* ``radius`` is ``R`` in the formula above, i.e. the 1/e half-width of a spot
  (intensity falls to 1/e at distance R; the Gaussian's standard deviation is
  ``R / sqrt(2)``). The paper's "speckle size 4 px" is read as R = 4. If it
  meant the spot diameter, use ``radius=2.0``.
* Centres fill an enlarged domain (the image plus ``margin`` px on every side)
  at one density, so the borders are never depleted after a displacement.
  ``n_speckles`` (or ``density``) counts speckles whose centre lies in the
  image's pixel footprint ``[-0.5, W - 0.5] x [-0.5, H - 0.5]``: exactly that
  many are drawn there, and ``round(density * frame area)`` more in the frame.
* Each spot is truncated at ``cutoff * R`` (default 5R). Omitted terms are each
  below ``exp(-cutoff**2)`` of I0; for uniformly scattered centres the expected
  omitted intensity is ``exp(-cutoff**2)`` times the mean image intensity
  (1.4e-11 for 5R), far below 8-16 bit quantisation.
* Integer images use ONE grey-scale factor per pattern, chosen so that the
  brightest pixel of the point-sampled float reference reaches ``fill`` (80 %)
  of full scale. Every image of that pattern (reference, deformed, pixel
  integrated) uses this factor; images are never normalised one by one, which
  would bias gradient-based sub-pixel methods.
* ``pixel_integration=True`` averages the intensity over each pixel's area
  ``[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]`` (a camera pixel rather than a
  point sample): exactly with the erf closed form for translations, and with a
  4 x 4 Gauss-Legendre quadrature of the inverse-mapped intensity for other
  fields (a numerical quadrature; measured against the erf form, its error
  relative to the mean intensity is about 1e-10 at R = 4, 2e-8 at R = 2 and
  5e-6 at R = 1).

The evaluation runs in numba kernels (``parallel=True``). Translations, the
reference included, "splat" each spot as the separable outer product of a row
and a column profile, threads owning bands of rows. Other fields work on
8 x 8 pixel tiles: a tile maps its pixels to the reference, gathers the centres
within the cutoff of that bounding box from a bin grid built once per pattern,
and sums them over its pixels with a branch-free polynomial exp (relative
error < 5e-14) that LLVM vectorises. Summation order is fixed, so results do
not depend on the number of threads.
"""

from livedic.dic.speckle.fields import DisplacementField, affine, sinusoid, translation
from livedic.dic.speckle.intensity import GAUSS_LEGENDRE_ORDER, INVERSE_TOLERANCE
from livedic.dic.speckle.pattern import DEFAULT_CUTOFF, DEFAULT_FILL, SpecklePattern
from livedic.dic.speckle.render import render

__all__ = ["DEFAULT_CUTOFF", "DEFAULT_FILL", "GAUSS_LEGENDRE_ORDER", "INVERSE_TOLERANCE", "DisplacementField",
           "translation", "affine", "sinusoid", "SpecklePattern", "render"]
