"""What the recording readers return: one frozen record per recorded message (``Recorded*``), and
``RecordingInfo``, what a pass over a file found.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from livedic.acquire.recording import schema as rs
from livedic.acquire.recording import wire
from livedic.dic.result import Measurement
from livedic.dic.strain.extensometer import ExtensometerReadings

__all__ = ["RecordedEvent", "RecordedExtensometerSample", "RecordedForceSample", "RecordedResults", "RecordedStrain",
           "RecordingInfo"]

_MEASURED = ("x", "y", "u", "v", "zncc", "ok", "status", "ux", "uy", "vx", "vy", "iterations")


def _measured(name: str) -> Any:
    return property(lambda self: getattr(self.measurement, name), doc=f"``measurement.{name}``")


@dataclass(frozen=True)
class RecordedResults:
    """One frame's results as recorded on ``/dic/results``.

    ``measurement`` is what the tracker measured, as a ``dic.result.Measurement``
    (``evaluations`` is not recorded: None); its arrays are also attributes of the
    record: ``x, y, u, v, zncc, ok`` and ``status, ux, uy, vx, vy, iterations``
    (None when they were not recorded). Arrays have shape (N,): ``point_id`` uint32,
    ``ok`` bool, ``status``/``iterations`` int32/uint32, the rest float64. They may
    be read-only views into the file data. ``stereo``: a stereo session's 3D arrays by name
    (``schema.STEREO_ARRAYS``: X, Y, Z, U, V, W in mm, the 3D status, the right image positions), empty in 2D.
    """
    frame_index: int
    timestamp_ns: int
    point_id: np.ndarray
    measurement: Measurement
    method: str = ""
    processing_ns: int = 0
    latency_ns: int = 0
    reference_frame_index: int = 0
    dropped_frames: int = 0
    publish_time_ns: int = 0            # host clock when the recorder wrote it
    stereo: Mapping[str, np.ndarray] = field(default_factory=dict)   # a stereo frame's ``rs.STEREO_ARRAYS``

    x = _measured("x")
    y = _measured("y")
    u = _measured("u")
    v = _measured("v")
    zncc = _measured("zncc")
    ok = _measured("ok")
    status = _measured("status")
    ux = _measured("ux")
    uy = _measured("uy")
    vx = _measured("vx")
    vy = _measured("vy")
    iterations = _measured("iterations")


def recorded_results(values: Mapping[str, Any], publish_time_ns: int) -> RecordedResults:
    """``RecordedResults`` from ``wire.decode_results`` values."""
    return RecordedResults(
        frame_index=values["frame_index"], timestamp_ns=values["timestamp_ns"], point_id=values["point_id"],
        measurement=Measurement(**{name: values[name] for name in _MEASURED}), method=values["method"],
        processing_ns=values["processing_ns"], latency_ns=values["latency_ns"],
        reference_frame_index=values["reference_frame_index"], dropped_frames=values["dropped_frames"],
        publish_time_ns=publish_time_ns,
        stereo={name: values[name] for name in rs.STEREO_ARRAYS if values.get(name) is not None})


@dataclass(frozen=True)
class RecordedStrain:
    """One frame's strain field as recorded on ``/dic/strain`` (``livedic.StrainField``).

    Arrays have shape (N,), in the order of the frame's ``/dic/results`` points:
    ``point_id`` uint32, ``status`` int32 (``dic.strain.StrainStatus`` codes), the
    strains float64 (NaN where ``status`` is not 0). ``window`` is 0 when it was not
    recorded.
    """
    frame_index: int
    timestamp_ns: int
    point_id: np.ndarray
    exx: np.ndarray
    eyy: np.ndarray
    exy: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    status: np.ndarray
    measure: str
    window: int
    vsg_px: float

    @property
    def ok(self) -> np.ndarray:
        return self.status == 0


@dataclass(frozen=True)
class RecordedExtensometerSample:
    """One extensometer's reading in one frame, as recorded on ``/dic/extensometers``.

    ``l_px``, ``eng_strain`` and ``true_strain`` are NaN where ``ok`` is False;
    ``status`` is a ``dic.strain.extensometer.ExtensometerStatus`` code. ``l0_mm`` and ``l_mm``: a stereo
    session's lengths in space (mm), None in 2D recordings.
    """
    frame_index: int
    timestamp_ns: int
    name: str
    l0_px: float
    l_px: float
    eng_strain: float
    true_strain: float
    ok: bool
    status: int
    l0_mm: float | None = None
    l_mm: float | None = None


@dataclass(frozen=True)
class RecordedForceSample:
    """The machine's force on one tracked frame, as recorded on ``/machine/force``.

    ``force_N`` is NaN (and ``ok`` False) where the load had no value for the frame;
    ``stress_MPa`` (engineering) is NaN where the session had no cross-section;
    ``source`` is the load URI.
    """
    frame_index: int
    timestamp_ns: int
    force_N: float
    stress_MPa: float
    ok: bool
    source: str


_STRAIN_FLOATS = ("exx", "eyy", "exy", "e1", "e2")


def recorded_strain(message: Any) -> RecordedStrain:
    """``RecordedStrain`` from a decoded ``livedic.StrainField``; WireError when its arrays differ in length."""
    arrays = {"point_id": np.array(message.point_id, dtype=np.uint32),
              "status": np.array(message.status, dtype=np.int32)}
    arrays.update({name: np.array(getattr(message, name), dtype=np.float64) for name in _STRAIN_FLOATS})
    lengths = {name: len(array) for name, array in arrays.items()}
    if len(set(lengths.values())) > 1:
        raise wire.WireError("strain arrays differ in length: "
                           + ", ".join(f"{name} {n}" for name, n in lengths.items()))
    return RecordedStrain(frame_index=message.frame_index, timestamp_ns=message.timestamp_ns, measure=message.measure,
                          window=message.window, vsg_px=message.vsg_px, **arrays)


def frame_readings(samples: Sequence[RecordedExtensometerSample]) -> ExtensometerReadings:
    """``dic.strain.extensometer.ExtensometerReadings`` of one frame's samples, in recorded order."""
    return ExtensometerReadings(names=tuple(s.name for s in samples),
                                l0_px=np.array([s.l0_px for s in samples], dtype=np.float64),
                                length_px=np.array([s.l_px for s in samples], dtype=np.float64),
                                eng_strain=np.array([s.eng_strain for s in samples], dtype=np.float64),
                                true_strain=np.array([s.true_strain for s in samples], dtype=np.float64),
                                status=np.array([s.status for s in samples], dtype=np.int32),
                                **_lengths_in_space(samples))


def _lengths_in_space(samples: Sequence[RecordedExtensometerSample]) -> dict[str, np.ndarray]:
    """``l0_mm`` / ``length_mm`` of a stereo frame's samples; {} in 2D."""
    if not samples or any(s.l0_mm is None for s in samples):
        return {}
    return {"l0_mm": np.array([s.l0_mm for s in samples], dtype=np.float64),
            "length_mm": np.array([s.l_mm for s in samples], dtype=np.float64)}


@dataclass(frozen=True)
class RecordedEvent:
    """A note from ``/livedic/events``."""
    timestamp_ns: int
    kind: str
    message: str
    level: str


@dataclass
class RecordingInfo:
    """What a reader found in a recording (see ``inspect_recording``); updated by each pass over it."""
    path: str
    size_bytes: int
    indexed: bool = False             # read through a valid summary/index
    truncated: bool = False           # data ends early: no DataEnd/footer (crash, kill, disk full)
    library: str = ""
    is_livedic: bool = False
    message_counts: dict[str, int] = field(default_factory=dict)   # topic -> messages read
    valid_bytes: int = 0              # bytes of complete records (recovery scan)
    corrupt_chunks: int = 0           # skipped by ``recover``
    start_ns: int | None = None
    end_ns: int | None = None
    note: str = ""                    # one line for people, "" when all is normal

    @property
    def frames(self) -> int:
        return self.message_counts.get(rs.TOPIC_IMAGE, 0)
