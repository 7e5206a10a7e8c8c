"""``livedic export``'s pictures of the fields: maps (PNG), an overlay video (MP4) and VTK for ParaView.

What ``livedic export FILE.mcap -o DIR`` writes besides its CSV files (``stream.export.export``):

``maps/Q/Q_FFFFFF.png`` (``--maps``: any of ``u,v,exx,eyy,exy``, default all; ``none``)
    Quantity Q of frame F colour-mapped over that frame's camera image, for every ``--every``-th
    frame with results (default 10; the reference frame and the last frame always). The camera
    image is at full resolution at the bottom left of the picture, the title (quantity, frame,
    time since the reference frame) above it, the colour bar (quantity and unit) at the right.
``overlay_Q.mp4`` (``--video Q``, default ``eyy``; ``none``)
    The same picture of Q for every frame with results, at ``--video-fps`` (default 10) frames a
    second: MPEG-4 Part 2 (fourcc ``mp4v``) in an MP4 container, the codec the pip OpenCV wheel
    writes (it has no H.264 encoder). VLC, mpv, QuickTime, Windows' player and PowerPoint play it;
    web browsers do not.
``vtk/frame_FFFFFF.vtu`` and ``fields.pvd`` (``--vtk``, default; ``--no-vtk``)
    Every frame with results as a VTK unstructured grid (meshio): the points at their reference
    positions (x, y, 0 in image px: x right, y down), point data ``u, v, exx, eyy, exy, zncc, ok,
    status, point_id`` (the values of ``fields.csv``, bit for bit) and ``displacement`` (u, v, 0;
    ParaView's "Warp By Vector" shows the deformed shape), and a triangulated surface. ``fields.pvd``
    lists the files with each frame's time (s since the reference frame), so ParaView plays them as
    a time series.

How a map is drawn (as VIC, ARAMIS or Ncorr draw a contour overlay): the reference points are
triangulated once (Delaunay, ``matplotlib.tri``), leaving out triangles with an edge longer than
``LONG_EDGE`` grid steps (they would bridge a gap in the grid: a mask, the image edge). In each
frame the triangles move with their corners to the deformed positions (x + u, y + v) and the
value is interpolated linearly over each one (the field is exact where it is affine). A triangle
is left out where a corner is not ok or has no value (NaN: a point not tracked, no strain), and
where its corners fold over (a wrong point): there the camera image shows, never a colour.

Colours: matplotlib's ``turbo`` (the live view's map), one fixed range per quantity for the whole
sequence, so a colour means the same value in every frame: ``--map-range Q=LO,HI`` (the unit of
the colour bar), or automatic, by the live view's rule over all the frames (``stream.view.colour_scale.
grow_limits``: the 0.5th/99.5th percentiles of each frame's values, the ends moving out to round
numbers, from +-0.05 px or +-0.1 % strain). Values beyond the range take the end colours.
Displacements in px, or mm with ``--scale``; strain in % (``--strain-unit microstrain``).

Every file is written whole or not at all (``acquire.atomic_file``): an export stopped halfway
leaves the pictures finished so far, each complete, and no video or ``.pvd``.

The parts: ``field_options`` (the options, file names, quantities and colour ranges), ``field_maps`` (the
surface, the pixels of each triangle, the picture), ``vtk`` (VTK and ``.pvd``), ``field_writer`` (the pass
that writes them); this module re-exports what ``stream.cli`` uses.
"""

# The field pictures' front door: stream.cli and the tests import these from here.
from livedic.stream.export.field_options import NO_FIELDS, FieldOptions, add_field_arguments
from livedic.stream.export.field_writer import FieldReport, FieldWriter

__all__ = ["NO_FIELDS", "FieldOptions", "FieldReport", "FieldWriter", "add_field_arguments"]
