"""Poisson's ratio in a session: the ``axial`` and ``transverse`` readings (and the force) kept, fitted.

``ContractionWatch`` is a session sink placed after the strain and load stages when the
session has the ``axial``/``transverse`` pair (``--gauge-length``). It keeps each frame's two
engineering strains (NaN without a reading) and force (NaN without one), and fits
``dic.tensile.poisson.contraction_ratios`` on them: Poisson's ratio over the elastic range, labelled
"Poisson's ratio (elastic, frames a-b, axial strain x-y %)", and the plastic contraction ratio
apart (never called Poisson's ratio). The fit so far goes on each ``FrameResult``
(``result.poisson``) for the live view; it is refitted after ``n / REFIT_SHARE`` new frames (every frame at
first), and at most every ``REFIT_INTERVAL_S`` of the frames' clock: a fit is O(n) (~2 ms at 300 frames), and at
100 fps refitting every frame cost the output thread more than the recording (docs/guide/performance.md). The
summary holds both ratios as objects (``as_dict``). The static frames after the reference (``--static-frames``,
``stream.stages.noise_floor``) are no part of the test: left out, as ten copies of the origin would weigh the
fit and hide where the elastic range ends.
"""

from array import array

import numpy as np
import numpy.ma  # noqa: F401 - np.median imports it on its first call: ~80 ms holding the GIL in the output thread

from livedic.dic.tensile.poisson import contraction_ratios
from livedic.dic.strain.extensometer import AXIAL, TRANSVERSE

REFIT_SHARE = 50      # the live fit is redone after n / REFIT_SHARE new frames
REFIT_INTERVAL_S = 0.2  # ... and at most this often (frames' clock): a display's rate, not the camera's


def has_pair(strain):
    """Whether a ``StrainStage`` has the axial/transverse pair."""
    names = [e.name for e in strain.extensometers] if strain is not None else []
    return AXIAL in names and TRANSVERSE in names


class ContractionWatch:
    """Axial and transverse strain and force per frame, and Poisson's ratio fitted on them (a session sink)."""
    name = "Poisson's ratio"
    required = False

    def __init__(self, static_frames=0, refit_interval_s=REFIT_INTERVAL_S):
        self._static_left = int(static_frames)   # frames after the reference still to leave out
        self._refit_interval_ns = refit_interval_s * 1e9
        self.frames = array("q")
        self.axial = array("d")
        self.transverse = array("d")
        self.force = array("d")
        self.current = None              # the last live fit (dic.tensile.poisson.ContractionRatio)
        self._fitted_at = 0
        self._fitted_ns = 0              # the frame time of the last live fit

    def __call__(self, result, stats):
        if not result.is_reference and self._static_left > 0:
            self._static_left -= 1
            result.poisson = self.current
            return
        readings = result.extensometers
        self.frames.append(int(result.frame.index))
        self.axial.append(_reading(readings, AXIAL))
        self.transverse.append(_reading(readings, TRANSVERSE))
        force = result.force_N
        self.force.append(float("nan") if force is None else float(force))
        result.poisson = self.live(result.frame.timestamp_ns)

    def live(self, now_ns: int):
        """The elastic fit so far, refitted when enough new frames came and time passed (see the module notes);
        ``now_ns``: the frame's time."""
        n = len(self.frames)
        if self.current is None or (n - self._fitted_at >= max(1, n // REFIT_SHARE)
                                    and now_ns - self._fitted_ns >= self._refit_interval_ns):
            self.current = self.fit()[0]
            self._fitted_at, self._fitted_ns = n, now_ns
        return self.current

    def fit(self):
        """(Poisson's ratio, plastic contraction ratio) over every frame so far (``dic.tensile.poisson``)."""
        force = np.asarray(self.force)
        return contraction_ratios(np.asarray(self.axial), np.asarray(self.transverse),
                                  force=force if np.isfinite(force).any() else None,
                                  frames=np.asarray(self.frames))

    def summary(self):
        """``{"poisson_ratio": {...}, "plastic_contraction_ratio": {...}}`` (``ContractionRatio.as_dict``)."""
        nu, plastic = self.fit()
        return {"poisson_ratio": nu.as_dict(), "plastic_contraction_ratio": plastic.as_dict()}


def _reading(readings, name):
    if readings is None or name not in readings.names:
        return float("nan")
    strain, _, ok = readings.reading(name)
    return strain if ok else float("nan")


_RANGE_WORDS = {"force": "below the proportional limit, where force vs axial strain is linear",
                "linear_part": "the initial linear part of transverse vs axial"}


def format_poisson(item, digits=3):
    """"LABEL = 0.300 +- 0.002 (range: ...)" or "LABEL: n/a (reason)" from an ``as_dict`` object."""
    value = item.get("value")
    if value is None or not np.isfinite(value):
        return f"{item['label']}: n/a ({item['reason']})"
    error = item.get("stderr")
    spread = f" +- {error:.{digits}f}" if error is not None and np.isfinite(error) else ""
    where = ("every frame: transverse vs axial never left its line, nothing tells elastic from plastic"
             if item.get("linear_to_end") else _RANGE_WORDS.get(item.get("basis"), ""))
    return f"{item['label']} = {value:.{digits}f}{spread}" + (f" (range: {where})" if where else "")
