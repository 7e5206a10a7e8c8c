"""Frame-to-frame tracking of points against a fixed reference (pure: no I/O, threads or display).

``Tracker`` measures every new frame against the *reference* frame (total,
Lagrangian displacement, so errors do not accumulate from frame to frame),
but starts each point from its result in the previous frame:

1. **Seeded search.** The integer search (default the improved WSO) looks only
   ``seed_radius`` px around the previous displacement: between two frames of a
   live test points move a fraction of a pixel, so a small box is enough and cheap.
   ``search="none"`` skips it and starts the sub-pixel method straight from the
   previous result. With the iterative sub-pixel methods (IC-GN, Newton-Raphson),
   which converge from any start within about a speckle of the answer, the seeded
   search runs *on demand*: every point is first refined from its previous result,
   and only the doubtful ones (failed, ZNCC below ``refind_zncc``, ZNCC drop or
   gradient jump, as for re-finding) are searched in the seed box and refined
   again, keeping the better match. Measured on the 1 MP simulated tensile test
   (1,059 points, 300 frames, 2-core machine): the same errors to the last digit
   (RMS 0.0113 px, max 0.1138 px) as searching every point every frame, at
   11.8 ms instead of 27.5 ms a frame (``livedic bench live`` reruns it). The
   surface-fit methods need an integer peak, so they always search.
2. **Sub-pixel refinement** with the chosen method. For ``"icgn"`` the
   reference data (subsets, gradients, Hessians) are prepared once in the
   constructor (``dic.subpixel.icgn.prepare_reference``), each frame is
   prefiltered once (``prepare_target``), and the iteration starts from the
   previous frame's displacement *gradients* as well, so a specimen that keeps
   stretching converges in a few iterations. ``"icgn2"`` (2nd-order shape
   function, ``dic.subpixel.icgn2``) works the same way with its 12-parameter
   reference data and starts from the previous frame's second-order terms too;
   a point without them (the first frame, a re-found point) is refined to first
   order first. Points it re-finds from a neighbour are propagated by
   first-order IC-GN, then refined by icgn2.
3. **Re-finding.** A point that failed, or whose ZNCC is below ``refind_zncc``,
   or fell by more than ``refind_drop`` since the previous frame, is searched
   again over ``refind_radius`` px around its last good displacement (or that
   of its nearest good neighbour) and refined; the new match is kept if it
   correlates better. This recovers points after a sudden jump (a grip slip, a
   knock on the camera) that the small seed box cannot reach. A point that the
   wide search cannot recover (it left the specimen, its paint flaked off) is
   retried after 1, 2, 4 ... up to ``REFIND_MAX_WAIT`` frames, so a few lost
   points do not cost a wide search on every frame.

Points whose reference subset is unusable (outside the image, no texture) are
reported with their status every frame and never searched.

Where a frame's time goes: ``Tracker.last_timings`` holds the nanoseconds of the last
``track`` call per stage (``TRACKER_STAGES``; ``StageTimes``), measured with a few
``time.perf_counter_ns`` calls; what they leave out of the call's wall time is the
bookkeeping between them (start values, scattering results, remembering the frame).

Modules: tracker (``Tracker``), grid (where its points go), kernel_job (one IC-GN kernel run), key_frames
(``KeyFrameTracker``: the reference follows the test) and update_policy (when it moves).
"""

from livedic.dic.tracking.grid import grid_in_roi, step_for_count
from livedic.dic.tracking.kernel_job import KernelJob, window_coefficients
from livedic.dic.tracking.refind import REFIND_SEEDS
from livedic.dic.tracking.results import last_good_after
from livedic.dic.tracking.tracker import (ICGN_MAX_ITERATIONS, REFIND_MAX_WAIT, REFIND_ZNCC, SEED_SWARM,
                                          TRACKER_STAGES, StageTimes, Tracker)

__all__ = ["ICGN_MAX_ITERATIONS", "REFIND_MAX_WAIT", "REFIND_SEEDS", "REFIND_ZNCC", "SEED_SWARM", "TRACKER_STAGES",
           "StageTimes",
           "grid_in_roi", "step_for_count", "Tracker", "window_coefficients", "KernelJob", "last_good_after"]
