"""The stereo panels of the view: the right camera with its points, and the 3D points coloured by W and by e_yy.

``RerunLogger`` draws them in a stereo session (``start(stereo=True)``; docs/guide/live-view.md), one log call per
entity per frame. The 3D points are shown in the specimen's frame (``dic.stereo.specimen_frame``: the reference
points' best-fit plane, x along the left camera's x, y along the image's y, z its normal pointing away from the
cameras), so the specimen lies flat in the view whatever the rig's angle to it, and W is the displacement along
that normal (positive away from the cameras). The frame is set up once, on the first frame with three measured
points or more, from their reference positions (xyz - displacement): the same whichever frame the view sees first.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from livedic.dic.stereo import SpecimenFrame, StereoPoints, specimen_frame
from livedic.stream.view.colour_scale import typical_spacing
from livedic.stream.view.entities import (
    CAMERA_RIGHT_IMAGE, CAMERA_RIGHT_POINTS, LEGEND_EYY, LEGEND_W, LIMITS_W, LIMITS_W_STYLE, SPACE, SPACE_EYY, SPACE_W)

if TYPE_CHECKING:
    import rerun as rerun_sdk

    from livedic.dic.stereo import StereoMeasurement

# the spheres' radius as a fraction of the points' typical spacing on the specimen: neighbours just touch,
# so the points read as a surface and a lost one as a hole
SPHERE_RADIUS_OF_SPACING = 0.5
RIGHT_POINT_RADIUS = -2.0       # UI points: the right view's speckle stays visible between the dots


@dataclass
class StereoView:
    """Draws a stereo session's own panels into the stream ``rec`` (``rr``: the rerun module).

    ``colours(legend, values)``: the packed colours of finite ``values`` on the automatic scale of ``legend``
    (the logger's, which grows the limits and logs its bar); ``scale``: the camera images' display factor;
    ``no_value_colour``: packed colour of a point without a value (grey, as in the 2D e_yy view).
    """

    rr: ModuleType
    rec: rerun_sdk.RecordingStream
    colours: Callable[[str, np.ndarray], np.ndarray]
    scale: int
    no_value_colour: np.uint32
    specimen: SpecimenFrame | None = None
    sphere_radius_mm: float = 0.5

    def start(self) -> None:
        """What does not change: the 3D space's axes (x right, y down, z away from the cameras) and W's limits'
        series names."""
        rr, rec = self.rr, self.rec
        rec.log(SPACE, rr.ViewCoordinates.RDF, static=True)
        names, colours = LIMITS_W_STYLE
        rec.log(LIMITS_W, rr.SeriesLines(names=names, colors=colours), static=True)

    def log(self, m: StereoMeasurement, strain: Any, right_image: np.ndarray | None) -> None:
        """One pair: the right image (when given: paced as the left one), the right view's points, the 3D points
        by W and, with ``strain`` (the frame's surface ``StrainField``, or None), by e_yy."""
        rr, rec = self.rr, self.rec
        if right_image is not None:
            rec.log(CAMERA_RIGHT_IMAGE, rr.Image(right_image))
        points = m.points
        if points is None:
            return
        ok = points.ok & np.all(np.isfinite(points.xyz), axis=1) & np.all(np.isfinite(points.displacement), axis=1)
        w_colours = np.zeros(0, dtype=np.uint32)
        if self.specimen is not None or self._set_up(points, ok):
            assert self.specimen is not None
            w_colours = self._log_space(points, ok, strain)
        self._log_right_points(m, ok, w_colours)

    def _set_up(self, points: StereoPoints, ok: np.ndarray) -> bool:
        """The specimen's frame and the spheres' size from the reference positions of the ``ok`` points; False
        while there are too few (under 3, or on a line)."""
        reference = points.xyz[ok] - points.displacement[ok]
        try:
            self.specimen = specimen_frame(reference)
        except ValueError:
            return False
        flat = self.specimen.to_specimen(reference)
        spacing = typical_spacing(flat[:, 0], flat[:, 1])
        if spacing is not None:
            self.sphere_radius_mm = SPHERE_RADIUS_OF_SPACING * spacing
        return True

    def _log_space(self, points: StereoPoints, ok: np.ndarray, strain: Any) -> np.ndarray:
        """The ok 3D points by W and by e_yy; returns their W colours (packed)."""
        rr, rec, specimen = self.rr, self.rec, self.specimen
        assert specimen is not None
        xyz = specimen.to_specimen(points.xyz[ok])
        w = specimen.turn(points.displacement[ok])[:, 2]
        w_colours = self.colours(LEGEND_W, w)
        rec.log(SPACE_W, rr.Points3D(xyz, radii=self.sphere_radius_mm, colors=w_colours))
        if strain is not None:
            eyy = strain.eyy[ok]
            has_strain = strain.ok[ok] & np.isfinite(eyy)
            colours = self.colours(LEGEND_EYY, np.where(has_strain, eyy, 0.0))
            colours[~has_strain] = self.no_value_colour
            rec.log(SPACE_EYY, rr.Points3D(xyz, radii=self.sphere_radius_mm, colors=colours))
        return w_colours

    def _log_right_points(self, m: StereoMeasurement, ok: np.ndarray, w_colours: np.ndarray) -> None:
        """Each point the right view tracks, where it sees it: coloured by W where the pair gives a 3D point,
        grey where not (not triangulated, or before the specimen's frame is set up)."""
        if m.right_xy is None or m.right_ok is None:
            return
        seen = m.right_ok & np.all(np.isfinite(m.right_xy), axis=1)
        colours = np.full(len(seen), self.no_value_colour, dtype=np.uint32)
        if w_colours.size:
            colours[ok] = w_colours
        self.rec.log(CAMERA_RIGHT_POINTS, self.rr.Points2D(m.right_xy[seen] / float(self.scale),
                                                           radii=RIGHT_POINT_RADIUS, colors=colours[seen]))
