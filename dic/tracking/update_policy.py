"""When a key-frame tracker moves its reference (``UpdatePolicy``: auto, never, every N frames) and what a
move reports (``ReferenceUpdate``); ``dic.tracking.key_frames``' docstring gives the rules and their reasons."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livedic.dic.result import Measurement
from livedic.dic.status import Status

# The auto policy's thresholds (dic.tracking.key_frames' docstring says why these values).
AUTO_ZNCC = 0.9
AUTO_STRAIN = 0.05
AUTO_OK = 0.99


@dataclass(frozen=True)
class UpdatePolicy:
    """When the reference moves (``dic.tracking.key_frames``' notes). Build it with ``UpdatePolicy.parse("auto" | "never" | "every:N")``."""
    mode: str = "auto"
    every: int = 0

    @classmethod
    def parse(cls, text: str | UpdatePolicy) -> UpdatePolicy:
        """``auto``, ``never`` or ``every:N`` (N >= 1); ValueError (one line) otherwise."""
        if isinstance(text, UpdatePolicy):
            return text
        word = str(text).strip().lower()
        if word in ("auto", "never"):
            return cls(word)
        if word.startswith("every:"):
            try:
                n = int(word[6:])
            except ValueError:
                n = 0
            if n >= 1:
                return cls("every", n)
        raise ValueError(f"--reference-update {text!r}: choose auto, never or every:N (N >= 1 frames)")

    def __str__(self):
        return f"every:{self.every}" if self.mode == "every" else self.mode

    def reason(self, frames_since_key: int, measurement: Measurement, trackable: np.ndarray) -> str | None:
        """Why the frame just tracked should become the reference, or None.

        ``measurement`` is its result on the current key frame's points, ``trackable`` the points
        tracked there.
        """
        if self.mode == "never":
            return None
        # a point whose subset has left the image (the material went out of view) says nothing against
        # the frame: it is not counted (on the real dog-bone 53 of ~1,000 points leave at the top, and
        # the reference never moved)
        trackable = trackable & (measurement.status != int(Status.OUTSIDE_TARGET))
        ok = measurement.ok & trackable
        tracked = int(trackable.sum())
        if tracked == 0:
            return None
        if self.mode == "every":
            return f"every {self.every} frames" if frames_since_key >= self.every else None
        if ok.sum() < AUTO_OK * tracked:
            return None                             # not a frame to measure the next ones against
        zncc = measurement.zncc[ok]
        if _percentile_may_pass(zncc, 5, AUTO_ZNCC, below=True):
            low = float(np.percentile(zncc, 5))
            if low < AUTO_ZNCC:
                return f"ZNCC 5th percentile {low:.3f} < {AUTO_ZNCC}"
        if measurement.ux is not None:
            ux, uy, vx, vy = (np.abs(getattr(measurement, name)[ok]) for name in ("ux", "uy", "vx", "vy"))
            finite = np.isfinite(ux) & np.isfinite(uy) & np.isfinite(vx) & np.isfinite(vy)
            if finite.any():
                largest = np.maximum(np.maximum(ux, uy), np.maximum(vx, vy))[finite]    # each point's largest
                if _percentile_may_pass(largest, 99, AUTO_STRAIN, below=False):
                    strain = float(np.percentile(largest, 99))
                    if strain > AUTO_STRAIN:
                        return f"strain since the key frame {strain:.3f} > {AUTO_STRAIN}"
        return None


def _percentile_may_pass(values, q, limit, *, below):
    """False when np.percentile(values, q) (finite values, linear interpolation) is surely not below ``limit``
    (``below``) or surely not above it: it lies between the two order statistics around rank q/100 (n - 1),
    and counting the values beyond ``limit`` places those without sorting (most frames pass far from it)."""
    rank = q / 100.0 * (values.size - 1)
    lower = int(np.floor(rank))
    upper = min(lower + 1, values.size - 1)
    if below:       # below limit needs the lower order statistic below it: more than `lower` values are
        return int(np.count_nonzero(values < limit)) > lower
    return int(np.count_nonzero(values > limit)) > values.size - 1 - upper


@dataclass(frozen=True)
class ReferenceUpdate:
    """One move of the reference.

    Attributes
    ----------
    frame : int
        Which tracked frame became the reference (0 is the first frame tracked).
    reason : str
    carried : int
        Points placed in it from their own result there.
    estimated : int
        Points placed from their neighbours (not trusted in that frame, or lost at an earlier update).
    lost : int
        Points that could not be placed (``Status.NOT_IN_KEY_FRAME`` until an update places them).
    seconds : float
        Time the update took.
    """
    frame: int
    reason: str
    carried: int
    estimated: int
    lost: int
    seconds: float

    def describe(self) -> str:
        text = f"reference moved to tracked frame {self.frame} ({self.reason}): {self.carried} points carried"
        if self.estimated:
            text += f", {self.estimated} placed from their neighbours"
        if self.lost:
            text += f", {self.lost} lost"
        return text + f", {1e3 * self.seconds:.1f} ms"
