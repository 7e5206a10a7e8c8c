"""Stereo DIC, the measurement: left -> right matching on the reference pair (match), triangulation to 3D
(triangulate), per-frame 3D points and displacements U, V, W and 3D extensometers (frame), strain in the
specimen's tangent plane (surface_strain), each pair tracked and triangulated (tracker). Pure functions on arrays; the guide: docs/guide/stereo.md."""

from livedic.dic.stereo.frame import (Extensometer3D, SpecimenFrame, StereoPoints, extensometer_3d, follow,
                                      right_track_points, specimen_frame, stereo_points, tangent_basis)
from livedic.dic.stereo.match import DEPTH_RANGE, MIN_STEREO_ZNCC, StereoMatch, match_stereo, working_distance
from livedic.dic.stereo.status import StereoStatus
from livedic.dic.stereo.surface_strain import SURFACE_MEASURE, SurfaceWindow, surface_strain, surface_window
from livedic.dic.stereo.tracker import StereoMeasurement, StereoTracker
from livedic.dic.stereo.triangulate import DEFAULT_MAX_EPIPOLAR_PX, Triangulation, project, triangulate

__all__ = ["DEFAULT_MAX_EPIPOLAR_PX", "DEPTH_RANGE", "MIN_STEREO_ZNCC", "Extensometer3D", "SURFACE_MEASURE", "SpecimenFrame",
           "StereoPoints", "StereoMatch", "StereoMeasurement", "StereoTracker", "StereoStatus", "SurfaceWindow", "Triangulation", "extensometer_3d",
           "follow", "match_stereo", "project", "right_track_points", "specimen_frame", "stereo_points",
           "surface_strain", "surface_window", "tangent_basis", "triangulate", "working_distance"]
