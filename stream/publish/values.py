"""What goes out for one frame: ``FrameValues`` (its extensometers' strain, valid or not), and its JSON datagram."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    from livedic.acquire.base import Frame
    from livedic.dic.strain.extensometer import ExtensometerReadings
    from livedic.stream.pipeline.frame_result import FrameResult


@dataclass(frozen=True)
class FrameValues:
    """What goes out for one frame (see ``stream.publish.stage``'s notes); arrays in the order of the extensometers."""
    frame: int
    time_s: float
    names: tuple[str, ...]
    eng_strain: tuple[float, ...]
    true_strain: tuple[float, ...]
    valid: tuple[bool, ...]

    @property
    def ok(self) -> bool:
        """True when every extensometer has a valid reading (False with none at all)."""
        return bool(self.valid) and all(self.valid)

    def as_json(self) -> bytes:
        """The UDP datagram: compact UTF-8 JSON, ``null`` for every missing number (never NaN)."""
        def number(value: float | None, valid: bool = True) -> float | None:
            return float(value) if valid and value is not None and math.isfinite(value) else None

        message = {"frame": int(self.frame), "time_s": float(self.time_s),
                   "strain": {n: number(e, v) for n, e, v in zip(self.names, self.eng_strain, self.valid)},
                   "ok": self.ok,
                   "true_strain": {n: number(t, v) for n, t, v in zip(self.names, self.true_strain, self.valid)}}
        return json.dumps(message, allow_nan=False, separators=(",", ":")).encode("utf-8")


def frame_values(result: FrameResult, names: Sequence[str], time_s: float) -> FrameValues:
    """The ``FrameValues`` of a ``stream.pipeline.frame_result.FrameResult`` for the extensometers ``names``.

    A reading is valid when its extensometer is ok and its strain finite; an extensometer the
    frame has no reading of (the strain stage failed) is not valid.
    """
    readings = cast("ExtensometerReadings | None", result.extensometers)   # FrameResult's field is untyped
    eng, true, valid = [math.nan] * len(names), [math.nan] * len(names), [False] * len(names)
    if readings is not None:
        index = {name: i for i, name in enumerate(readings.names)}
        for k, name in enumerate(names):
            i = index.get(name)
            if i is None:
                continue
            eng[k], true[k] = float(readings.eng_strain[i]), float(readings.true_strain[i])
            valid[k] = bool(readings.ok[i]) and math.isfinite(eng[k])
    frame = cast("Frame", result.frame)
    return FrameValues(frame=int(frame.index), time_s=time_s, names=tuple(names), eng_strain=tuple(eng),
                       true_strain=tuple(true), valid=tuple(valid))
