"""The machine's force in ``livedic export`` and ``report``: the force recorded on ``/machine/force``
(``RecordedForce``) or a ``--load`` file, the options that choose between them (``stress_from_args``), and
the stress-strain files written from it (``STRESS_FILES``).
"""

from __future__ import annotations

import argparse
import math
import os
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from livedic.stream.output.csv_text import csv_rows
from livedic.stream.export.notes import plural, reader_notes, session_or_note

if TYPE_CHECKING:
    from livedic.acquire.atomic_file import AtomicFile
    from livedic.acquire.force import LoadSource
    from livedic.acquire.recording.reader import Recording
    from livedic.stream.stages.stress import StressOptions


class RecordedForce:
    """The force recorded on ``/machine/force``, one value per tracked frame.

    Attributes
    ----------
    forces : dict
        Frame index -> force (N; NaN where the load had no value for that frame).
    source : str
        The load URI the session recorded (the last one seen; "" when none was written).
    """

    def __init__(self, forces: Mapping[int, float], source: str = "") -> None:
        self.forces = dict(forces)
        self.source = str(source)

    @classmethod
    def read(cls, recording: Recording) -> RecordedForce:
        """The force samples of a ``Recording`` (an empty ``forces`` for recordings without them)."""
        forces: dict[int, float] = {}
        source = ""
        for sample in recording.force_samples():
            forces[int(sample.frame_index)] = float(sample.force_N)
            source = sample.source or source
        return cls(forces, source)

    def on_frames(self, frames: Iterable[int]) -> np.ndarray:
        """Force at each of ``frames`` (indices): the recorded value, NaN for a frame without one."""
        return np.array([self.forces.get(int(frame), math.nan) for frame in frames], dtype=np.float64)


def _force_on_frames(load: LoadSource | RecordedForce, frames: Sequence[int], times: npt.ArrayLike) -> np.ndarray:
    """Force per frame: by frame index from the recording, or the load interpolated onto ``times``."""
    if isinstance(load, RecordedForce):
        return load.on_frames(frames)
    return load.force_at(np.asarray(times, dtype=np.float64))


def _force_label(stress: StressOptions) -> str:
    """What the plot title calls the force: the file's name, or the recorded channel."""
    from livedic.acquire.recording.schema import TOPIC_FORCE
    if stress.recorded:
        return f"recorded {TOPIC_FORCE}"
    return os.path.basename(stress.load[len('csv:'):])


def _open_stress_load(stress: StressOptions | None, names: Sequence[str],
                      recording: Recording) -> LoadSource | RecordedForce | None:
    """The ``LoadSource`` of ``stress``, or the ``RecordedForce`` of ``recording`` (None without ``stress``).

    ValueError (one line) if there is no axial extensometer."""
    if stress is None:
        return None
    from livedic.acquire.force import open_load
    from livedic.dic.strain.extensometer import AXIAL
    if AXIAL not in names:
        raise ValueError(f"the stress-strain curve needs an '{AXIAL}' extensometer, and this recording has "
                         f"{'only ' + ', '.join(names) if names else 'none'}: add --gauge-length L[,W] "
                         f"(or --extensometer {AXIAL}=x1,y1,x2,y2)")
    if stress.recorded:
        return RecordedForce.read(recording)
    return open_load(stress.load, offset_s=stress.offset_s)


def stress_from_args(args: argparse.Namespace) -> tuple[StressOptions | None, list[str]]:
    """``StressOptions`` of ``livedic export`` / ``report`` and note lines for people.

    With ``--load``, that load (a note when the recording also holds force samples, which it
    replaces); without, the force recorded on ``/machine/force`` when the recording holds some
    (A0 from the options or the session's ``area_mm2``), else None. Bad options raise before the
    recording is read; ValueError (one line) as ``stream.stages.stress.stress_options_from_args``.
    """
    from livedic.acquire.recording.reader import Recording
    from livedic.acquire.recording.schema import TOPIC_FORCE
    from livedic.stream.stages.stress import stress_options_from_args
    load = getattr(args, "load", None)
    section = any(getattr(args, name, None) is not None for name in ("area", "width", "thickness"))
    if load is not None and section:
        stress = stress_options_from_args(args)               # bad options: one line, before anything is read
    with reader_notes():                                      # the command's own read reports them, once
        recording = Recording(os.fspath(args.recording))
        recorded = RecordedForce.read(recording)
        metadata = session_or_note(recording)[0] if recorded.forces or (load is not None and not section) else {}
    if load is not None:
        if not section:                                       # A0 from the session, when it recorded one
            stress = stress_options_from_args(args, metadata=metadata)
        notes = [f"--load {stress.load} is the force here, not the one recorded on {TOPIC_FORCE} "
                 f"({plural(len(recorded.forces), 'frame')})"] if recorded.forces else []
        return stress, notes
    return stress_options_from_args(args, recorded_force=bool(recorded.forces), metadata=metadata), []


def _write_stress_strain(staged: Mapping[str, AtomicFile], load: LoadSource | RecordedForce, area_mm2: float,
                         frames: Sequence[int], times: Sequence[float], eng: np.ndarray, names: Sequence[str], *,
                         title: str) -> dict[str, Any]:
    """Write ``STRESS_FILES`` into ``staged``; returns what ``session.json`` says of them."""
    from livedic.dic.strain.extensometer import AXIAL
    from livedic.stream.stages.stress import (force_coverage_notes, plot_stress_strain, stress_strain_rows,
                                       stress_strain_table)
    time_s = np.asarray(times, dtype=np.float64)
    force = _force_on_frames(load, frames, time_s)
    table = stress_strain_table(frames, time_s, force, eng[:, list(names).index(AXIAL)], area_mm2)
    staged["stress_strain.csv"].write(stress_strain_rows(table, csv_rows))
    plot_stress_strain(staged["stress_strain.png"].handle, table, title=title)
    return {"frames_with_force": int(np.isfinite(force).sum()), "uniform_frame_row": table.uniform_frame,
            "uniform_frame": int(table.frame[table.uniform_frame]) if table.uniform_frame >= 0 else -1,
            "notes": force_coverage_notes(table.frame, table.time_s, table.force_N, table.eng_strain)}
