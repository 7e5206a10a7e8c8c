"""livedic's measurement core: pure functions on numpy arrays.

Correlation (ZNCC), integer-pixel search (exhaustive, FFT-CC, coarse-fine, PSO,
WSO, improved WSO), sub-pixel refinement (surface fit, gradient, Newton-Raphson,
improved surface fit, IC-GN), quality gates, frame-to-frame tracking and an exact
speckle simulator. No I/O, no threads.

The front door:

* ``measure`` -- displacements between two images; ``Measurement`` what it returns;
  ``SEARCH_METHODS``, ``SUBPIXEL_METHODS`` the method names it takes; ``Gates``
  its quality gates; ``Status`` the per-point codes.
* ``Tracker`` -- points tracked through the frames of a test; ``grid_in_roi`` and
  ``step_for_count`` place the points; ``TRACKER_STAGES`` the stages its ``last_timings`` times.
* ``zncc`` -- the correlation of given displacements; ``DEFAULT_SUBSET`` the subset side every function
  takes by default.
* ``strain_window``, ``strain_field`` -- strain at every point by pointwise least squares
  (``StrainField``, ``StrainStatus``); ``Extensometer``, ``place_extensometers``,
  ``read_extensometers`` -- virtual extensometers between material points.
"""

from livedic.dic.correlation import DEFAULT_SUBSET, zncc
from livedic.dic.measure import SEARCH_METHODS, SUBPIXEL_METHODS, measure
from livedic.dic.quality import Gates
from livedic.dic.result import Measurement
from livedic.dic.status import Status
from livedic.dic.strain import StrainField, StrainStatus, strain_field, strain_window
from livedic.dic.strain.extensometer import Extensometer, place_extensometers, read_extensometers
from livedic.dic.tracking import TRACKER_STAGES, Tracker, grid_in_roi, step_for_count

__all__ = ["DEFAULT_SUBSET",
           "measure", "Measurement", "SEARCH_METHODS", "SUBPIXEL_METHODS", "Gates", "Status", "Tracker", "TRACKER_STAGES",
           "grid_in_roi", "step_for_count", "zncc", "strain_window", "strain_field", "StrainField", "StrainStatus", "Extensometer",
           "place_extensometers", "read_extensometers"]
