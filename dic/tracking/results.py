"""What ``Tracker`` returns and the helpers on its rows: the second-order result inside a frame, rows taken
from a result, the last good values of each point, the inputs of the median test."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livedic.dic.result import Measurement
from livedic.dic.subpixel.icgn2 import SECOND_ORDER


def last_good_after(last_good: dict[str, np.ndarray] | None, result: Measurement) -> dict[str, np.ndarray]:
    """Each point's last ok result (``Tracker.resume``'s ``last_good``) once ``result`` has been tracked.

    ``last_good``: the dict before ``result`` (None: before the first frame, every value 0, never ok);
    ``result``: a ``Measurement`` (``u, v, ok`` and, when it has them, ``ux, uy, vx, vy``). The rule is
    the tracker's own: ok values replace, the others keep what was there.
    """
    ok = np.asarray(result.ok, dtype=bool)
    if last_good is None:
        last_good = {name: np.zeros(ok.size) for name in ("u", "v") + _SHAPE}
        last_good["ever"] = np.zeros(ok.size, dtype=bool)
    out = {"ever": last_good["ever"] | ok}
    for name in ("u", "v") + _SHAPE:
        values = getattr(result, name, None)
        out[name] = last_good[name] if values is None else np.where(ok, np.asarray(values, dtype=np.float64),
                                                                    last_good[name])
    return out


def _gradients_of(measurement):
    """(ux, uy, vx, vy) of a first-order result, or None."""
    if measurement.ux is None:
        return None
    return measurement.ux, measurement.uy, measurement.vx, measurement.vy


def _median_test_inputs(result, copy=False):
    """(ok, u, v and, where the result has them, ux, uy, vx, vy): what ``quality.median_test`` reads of it."""
    arrays = (result.ok, result.u, result.v) + (_gradients_of(result) or ())
    return tuple(np.array(a, copy=True) for a in arrays) if copy else arrays


def _same_bits(a, b):
    """Whether two arrays hold the same values bit for bit (NaN and the sign of zero included)."""
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _take(measurement, mask, kind=None):
    """The rows of ``measurement`` where ``mask`` is True (a new record of its kind, or of ``kind``)."""
    kind = kind or type(measurement)
    names = ("x", "y", "u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations", "evaluations")
    if kind is _Curved:
        names += SECOND_ORDER
    values = {}
    for name in names:
        array = getattr(measurement, name)
        values[name] = None if array is None else np.asarray(array)[mask]
    return kind(**values)


# Displacement-gradient names of a first-order result.
_SHAPE = ("ux", "uy", "vx", "vy")


@dataclass
class _Curved(Measurement):
    """A tracker result inside ``Tracker.track`` with a second-order method's terms (``icgn2.SECOND_ORDER``)."""
    uxx: np.ndarray | None = None
    uxy: np.ndarray | None = None
    uyy: np.ndarray | None = None
    vxx: np.ndarray | None = None
    vxy: np.ndarray | None = None
    vyy: np.ndarray | None = None
