"""``livedic export``'s pictures of the fields: maps (PNG), an overlay video (MP4) and VTK for ParaView.

What ``livedic export FILE.mcap -o DIR`` writes besides its CSV files (``stream.export.export``):

``maps/Q/Q_FFFFFF.png`` (``--maps``: any of ``u,v,exx,eyy,exy``, default all; ``none``)
    Quantity Q of frame F colour-mapped over that frame's camera image, every ``--every``-th
    frame with results (default 10; the reference frame and the last frame always).
``overlay_Q.mp4`` (``--video Q``, default ``eyy``; ``none``)
    The same picture of Q for every frame with results (MPEG-4 Part 2, ``mp4v``).
``vtk/frame_FFFFFF.vtu`` and ``fields.pvd`` (``--vtk``, default; ``--no-vtk``)
    Every frame with results as a VTK unstructured grid (meshio): the reference points, point
    data ``u, v, exx, eyy, exy, zncc, ok, status, point_id`` (``fields.csv``'s values, bit for
    bit), ``displacement`` and a triangulated surface; ``fields.pvd`` makes it a time series.

A map interpolates linearly over triangles between the points at their deformed positions; a
triangle with a corner not ok or without a value, or folded over, is left out: there the camera
image shows, never a colour. One colour range per quantity for the whole sequence
(``--map-range Q=LO,HI``, or automatic by the live view's rule); displacements in px, or mm
with ``--scale``; strain in % or ``--strain-unit microstrain``. Every file is written whole or
not at all (``acquire.atomic_file``). How the pictures are drawn: docs/guide/export.md ("How
the pictures are made").

The parts: ``field_options`` (the options, file names, quantities and colour ranges), ``field_maps`` (the
surface, the pixels of each triangle, the picture), ``vtk`` (VTK and ``.pvd``), ``field_writer`` (the pass
that writes them); this module re-exports what ``stream.cli`` uses.
"""

# The field pictures' front door: stream.cli and the tests import these from here.
from livedic.stream.export.field_options import NO_FIELDS, FieldOptions, add_field_arguments
from livedic.stream.export.field_writer import FieldReport, FieldWriter

__all__ = ["NO_FIELDS", "FieldOptions", "FieldReport", "FieldWriter", "add_field_arguments"]
