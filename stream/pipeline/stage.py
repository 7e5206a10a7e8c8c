"""What a pipeline stage is: ``Stage`` (the protocol), ``Reference`` (what it is set up on), ``check_stage_order``.

A stage runs in the tracking thread right after the tracker, on every frame's ``FrameResult``. It says which of
the result's fields it reads (``needs``) and which it sets (``provides``), sets itself up on the reference
(``on_reference``), handles a frame (``on_frame``), and gives its own part of the session's summary text and
recording metadata. The session checks the order of its stages once (``check_stage_order``) before it starts.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from livedic.stream.pipeline.frame_result import FrameResult, TRACKER_FIELDS, RESULT_FIELDS


@dataclass(frozen=True)
class Reference:
    """The reference frame's points, set when the tracker is built on it."""
    frame_index: int
    points: np.ndarray
    roi: tuple
    step: int | None
    shape: tuple
    timestamp_ns: int | None = None     # the reference frame's timestamp (``Frame.timestamp_ns``)


@runtime_checkable
class Stage(Protocol):
    """One step of the measurement in the tracking thread (see the module notes).

    Classes that implement it subclass it to take the defaults: nothing to set up on the reference, no
    summary lines, no metadata.

    Attributes
    ----------
    name : str
        How a warning names it.
    needs : tuple of str
        The ``FrameResult`` fields it reads (the tracker's, or an earlier stage's).
    provides : tuple of str
        The ``FrameResult`` fields it sets.
    required : bool
        True when the session cannot go on without it (its error ends the session).
    """
    name: str
    needs: ClassVar[tuple[str, ...]] = ()
    provides: ClassVar[tuple[str, ...]] = ()
    required: bool = False

    def on_reference(self, reference: Reference) -> None:
        """Set up on the reference (called once, when the tracker is built on it, before any ``on_frame``)."""

    def on_frame(self, result: FrameResult) -> None:
        """Handle one frame's result (the reference frame's first), setting the fields in ``provides``."""
        ...

    def summary_lines(self) -> list[str]:
        """This stage's lines of the session's summary text (aligned like the others), after the session."""
        return []

    def metadata(self) -> dict[str, Any]:
        """This stage's keys of the recording's session metadata, before the session."""
        return {}


class StageOrderError(ValueError):
    """A stage needs a field that no stage before it (nor the tracker) provides."""


def check_stage_order(stages: Sequence[Stage], *, tracked: Iterable[str] = TRACKER_FIELDS) -> None:
    """Raise ``StageOrderError`` unless each stage's ``needs`` are provided by the tracker (``tracked``) or an
    earlier stage, and every field named is a ``FrameResult`` field.

    Raises
    ------
    StageOrderError
        Names the stage, the field, and which stage provides it (when a later one does).
    """
    known = set(tracked)
    for i, stage in enumerate(stages):
        for field_name in (*stage.needs, *stage.provides):
            if field_name not in RESULT_FIELDS:
                raise StageOrderError(f"stage {stage.name!r}: {field_name!r} is not a FrameResult field")
        for field_name in stage.needs:
            if field_name in known:
                continue
            later = [s.name for s in stages[i + 1:] if field_name in s.provides]
            where = f"stage {later[0]!r} provides it after it" if later else "no stage provides it"
            raise StageOrderError(f"stage {stage.name!r} needs {field_name!r}, but {where}")
        known.update(stage.provides)
