"""Where points may go: the region of interest, masks and exclusions, and the speckled specimen.

A *region* is a boolean image, True where a subset may lie. It is built from an
outline (a rectangle or a polygon, ``--roi``), a mask image (``--mask``, white =
specimen) and exclusions (circles, rectangles, polygons: a hole, a clip, a
marker), or, when none is given, found in the reference image by its speckle
(``find_specimen``). A point is placed only where its whole subset lies inside
the region (``placeable``): no subset reaches into an excluded area, the
background or a hole.

Shapes are in image pixels: x along columns, y along rows, a pixel's centre at
integer coordinates; a pixel belongs to a shape when its centre does.

Finding the specimen. DIC needs texture in every direction inside a subset: the
smaller eigenvalue of the image's structure tensor (the mean of grad I grad I^T
over a speckle-sized window) is large on a speckle pattern and ~0 on a uniform
background, a saturated patch, a dark hole, and along a single straight edge
(where only one direction has texture). Its logarithm separates the two
populations by orders of magnitude on real images (Otsu's threshold on it); the
speckled pixels, cleaned of isolated specks and of gaps between speckles, and
kept in pieces large enough to hold several subsets, are the specimen. See
``find_specimen`` for the rules and their reasons.

Pure functions on numpy arrays (OpenCV for filters and polygon filling); no I/O. The package re-exports
the names of its modules: shapes, placement (regions and grids), specimen, and pattern_quality beside them.
"""

from livedic.dic.region.placement import (Region, bounding_box, centred_axis, grid_in_region, placeable, step_for_area,
                                          straddling)
from livedic.dic.region.shapes import Circle, Polygon, Rectangle, Shape, parse_shape, shape_mask
from livedic.dic.region.specimen import TEXTURE_WINDOW, Specimen, find_specimen, speckle_texture

__all__ = ["Rectangle", "Polygon", "Circle", "Shape", "Region", "Specimen", "shape_mask", "placeable", "straddling",
           "bounding_box", "centred_axis",
           "grid_in_region", "step_for_area", "speckle_texture", "find_specimen", "parse_shape",
           "TEXTURE_WINDOW"]
