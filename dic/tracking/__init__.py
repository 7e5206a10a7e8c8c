"""Frame-to-frame tracking of points against a fixed reference (pure: no I/O, threads or display).

``Tracker`` measures every new frame against the *reference* frame (total, Lagrangian
displacement, so errors do not accumulate from frame to frame), but starts each point from
its result in the previous frame:

1. **Seeded search.** The integer search looks ``seed_radius`` px around the previous
   displacement (``search="none"`` skips it). With the iterative sub-pixel methods (IC-GN,
   Newton-Raphson) it runs *on demand*: every point is first refined from its previous
   result, and only the doubtful ones (failed, low or falling ZNCC, gradient jump) are
   searched and refined again, keeping the better match. The surface-fit methods always search.
2. **Sub-pixel refinement** with the chosen method; for ``"icgn"``/``"icgn2"`` the reference
   data are prepared once, each frame is prefiltered once, and the iteration starts from the
   previous frame's gradients (and second-order terms) too.
3. **Re-finding.** A point that failed, or whose ZNCC is below ``refind_zncc`` or fell by more
   than ``refind_drop``, is searched over ``refind_radius`` px around its last good
   displacement (or its nearest good neighbour's); the better match is kept. A point the wide
   search cannot recover is retried after 1, 2, 4 ... up to ``REFIND_MAX_WAIT`` frames.

Points whose reference subset is unusable are reported with their status every frame and never
searched. ``Tracker.last_timings`` holds the nanoseconds of the last ``track`` call per stage
(``TRACKER_STAGES``; ``StageTimes``). What the on-demand search saves: docs/guide/performance.md
("The on-demand seeded search").

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
