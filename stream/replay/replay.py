"""``livedic replay``: re-run tracking offline on a recording's frames.

``livedic replay FILE.mcap [-o OUT.csv | -o OUT.parquet] [method options] [--all-frames]``

The recorded frames are tracked again by the session ``livedic run`` runs
(``stream.session.session.Session``), its ``TrackingConfig`` built from the recording's
metadata and the options given: with no options the replay repeats the live run. By default
exactly the frames with recorded results are tracked, in the recorded order, with the
recorded points, so with the recorded parameters ``u, v, zncc, ok`` are bit for bit the
recorded ones; ``--all-frames`` also tracks the frames the live run dropped; point options
rebuild the points on the reference frame as ``run`` does.

The output (``-o``, default stdout) is one row per frame and point:
``frame,timestamp_ns,point_id,x,y,u,v,zncc,ok`` then ``status`` and, for first-order
sub-pixel methods, ``ux,uy,vx,vy,iterations``, then ``exx,eyy,exy`` recomputed on the
replayed displacements (``stream.stages.strain``), at full precision; ``.parquet`` writes the
same columns typed (``stream.replay.rows``), any other suffix is refused. It is written under a
temporary name and renamed when complete: an error or Ctrl-C leaves no file. The comparison
with the recording is ``ReplayReport.agreement`` (an ``Agreement``: ``EXACT``,
``WITHIN_ROUNDING``, ``DIFFERS``, ``NOT_COMPARED``), said in one line on stderr.
``--workers N`` / ``--cluster ADDRESS`` run it on Dask (``stream.replay.parallel_replay``).

Which frames, the verdicts and the parallel replay: docs/guide/replay.md ("Which frames are
replayed, and with what", "Replay on many cores or machines (Dask)").
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, cast

import numpy as np

from livedic.dic.calibration import StereoCalibration
from livedic.dic.strain.extensometer import ExtensometerOffPoints
from livedic.stream.stages.noise_floor import STATIC_FRAMES_KEY
from livedic.stream.session.config import SessionConfig, TrackingConfig
from livedic.stream.replay.rows import FrameRows, frame_rows
from livedic.stream.session.session import NoFrame, Session
from livedic.stream.session.stereo import STEREO_KEY
from livedic.stream.stages.stereo_strain import nominal_px_per_mm
from livedic.stream.pipeline.sinks import FunctionSink
from livedic.stream.stages.strain import StrainConfig

from livedic.stream.export.notes import read_session_or_note, reader_notes
from livedic.stream.replay.agreement import ReplayReport, _Comparison
from livedic.stream.replay.parameters import METHOD_KEYS, check_parameters, resolve_parameters
from livedic.stream.replay.points import PointOptions, build_replay_points
# Re-exported: callers name them as replay's (stream.cli.replay, the tests).

if TYPE_CHECKING:
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.source import McapPairs, McapSource
    from livedic.acquire.recording.records import RecordedResults
    from livedic.acquire.stereo import PairingCounts
    from livedic.dic.result import Measurement
    from livedic.dic.strain.field import StrainField
    from livedic.stream.pipeline.frame_result import FrameResult, SessionStats
    from livedic.stream.stages.stress import StressOptions


def replay(path: str | os.PathLike[str], given: dict[str, Any] | None = None, *,
           point_options: PointOptions | None = None, all_frames: bool = False,
           on_result: Callable[..., None] | None = None, progress: Callable[[int], None] | None = None,
           threads: int = 1, strain: dict[str, Any] | None = None, workers: int | None = None,
           cluster: str | None = None, in_flight: int | None = None, shared_path: str | None = None,
           on_rows: Callable[[FrameRows], None] | None = None, stress: StressOptions | None = None,
           rig: StereoCalibration | None = None) -> ReplayReport:
    """Track the frames of recording ``path`` again; returns a ``ReplayReport``.

    Parameters
    ----------
    path : str
        A livedic recording (complete or truncated).
    given : dict, optional
        Method parameters to use instead of the recorded ones (``METHOD_KEYS``; None = recorded).
    point_options : PointOptions, optional
        Rebuild the points (default: the recorded ones).
    all_frames : bool
        Track every frame from the reference on, not only those with recorded results.
    on_result : callable, optional
        ``on_result(frame, measurement, point_ids, strain)`` for each tracked frame, in order
        (``strain``: its ``dic.strain.StrainField``).
    on_rows : callable, optional
        ``on_rows(rows)`` for each tracked frame, in order: its ``stream.replay.rows.FrameRows``. When
        ``on_rows.csv_text`` is true (``CsvRows``), a parallel replay formats the CSV lines on the worker that
        measured the frame and sends only them; else the columns.
    progress : callable, optional
        ``progress(frames_done)``.
    threads : int
        numba threads while tracking.
    strain : dict, optional
        Strain settings replacing the recorded ones (``stream.stages.strain.overrides_from_args``); the
        strain fields and extensometers are recomputed on the replayed displacements.
    workers : int, optional
        Measure the frames in parallel on a local Dask cluster of this many worker processes
        (``stream.replay.parallel_replay``); the outputs are the sequential replay's.
    cluster : str, optional
        ... on the Dask scheduler at this address (``tcp://HOST:8786``) instead.
    in_flight : int, optional
        Parallel: frames submitted ahead of the one being written (default 4 per worker thread).
    shared_path : str, optional
        Parallel: the workers read the frames from the recording at this path themselves ("": ``path``,
        made absolute) instead of receiving each image (``acquire.recording.source.FrameReader``).
    stress : stream.stages.stress.StressOptions, optional
        The machine's force (``--load csv:FILE``, its offset, A0): each frame's force and engineering
        stress, from the session's load stage as in ``livedic run``, become the rows' last columns
        (``FORCE_COLUMNS``) and ``report.force`` its summary.
    rig : dic.calibration.StereoCalibration, optional
        A stereo recording's rig calibration to use instead of the recorded one (``--calibration RIG.json``).

    Raises
    ------
    ValueError
        Bad parameters, or a recording that is missing, not MCAP, not livedic,
        corrupt, or holds nothing to replay (``RecordingError`` is a ValueError); in parallel
        also ``ClusterError`` (no scheduler at ``cluster``, no worker, livedic missing there) and
        a recording without results to seed the frames from (``--all-frames``) or a stereo recording; ``rig``
        with a recording that is not stereo.
    SourceError
        The frames cannot be read (``RecordingSourceError``).
    """
    path = os.fspath(path)
    point_options = point_options or PointOptions()
    point_options.check()
    request = _Request(path, given or {}, point_options, all_frames, on_result, progress, threads, strain, on_rows,
                       stress, rig)
    if workers is not None or cluster is not None:
        return _replay_on_dask(request, workers, cluster, in_flight, shared_path)
    return _replay(request)


def _replay_on_dask(request: _Request, workers: int | None, cluster: str | None, in_flight: int | None,
                    shared_path: str | None) -> ReplayReport:
    """``replay``'s frames measured on a Dask cluster (its options checked first, each in one line)."""
    from livedic.stream.replay.parallel_replay import (check_cluster_address, check_worker_count, check_workers,
                                                       dask_client)
    if workers is not None:
        check_worker_count(workers)
    if cluster is not None:
        check_cluster_address(cluster)          # its form, before the recording is read (one line otherwise)
    _check_parallel_input(request.path, request.given, request.all_frames, request.threads)
    if shared_path == "":
        from livedic.acquire.recording.source import FrameReader
        shared_path = os.path.abspath(request.path)
        FrameReader(shared_path)                # indexed? (one line otherwise)
    with dask_client(workers, cluster) as client:
        where = f"the Dask scheduler at {cluster}" if cluster is not None \
            else f"a local Dask cluster of {workers} worker process(es)"
        return _replay(request, _OnDask(client, in_flight, shared_path, where, list(check_workers(client))))


def _check_parallel_input(path: str, given: Mapping[str, Any] | None, all_frames: bool, threads: int | None) -> None:
    """What the parallel replay refuses before any cluster starts (one line, as the sequential replay words
    it, or its own): bad parameters, nothing to seed the frames from."""
    from livedic.acquire.recording.reader import Recording
    with reader_notes():                   # the replay itself says what the reader notes (a truncated file)
        metadata, _ = read_session_or_note(path)
        first = next(iter(Recording(path).results()), None)
    if metadata.get(STEREO_KEY):
        raise ValueError(f"{path} is a stereo recording: its replay runs in this process only for now (leave out "
                         f"--workers/--cluster)")
    params, _, _ = resolve_parameters(metadata, given or {}, first.method if first is not None else "")
    check_parameters(params, threads)
    if first is None and all_frames:
        raise ValueError(f"{path} holds no tracking results to seed the frames from: replay it without "
                         f"--workers/--cluster")


@dataclass
class _Request:
    """What ``replay`` was asked for (its parameters, ``path`` as a string, ``point_options`` checked)."""
    path: str
    given: dict[str, Any]
    point_options: PointOptions
    all_frames: bool
    on_result: Callable[..., None] | None
    progress: Callable[[int], None] | None
    threads: int
    strain: dict[str, Any] | None
    on_rows: Callable[[FrameRows], None] | None
    stress: StressOptions | None
    rig: StereoCalibration | None


@dataclass
class _OnDask:
    """Where and how a parallel replay measures its frames (``stream.replay.parallel_replay``)."""
    client: Any                              # a dask.distributed.Client
    in_flight: int | None
    shared_path: str | None
    where: str                               # the cluster, in words, for the report
    worker_notes: list[str] = field(default_factory=list)


@dataclass
class _Recorded:
    """What the replay takes from the recording: its metadata, its results keyed by (frame index, timestamp),
    the reference frame (by key, or by index when the first results are not the reference's) and the points of
    the first results (None without results); for a stereo recording its rig (the recorded one, or ``--calibration``)
    and where that came from."""
    metadata: dict[str, Any]
    results: list[RecordedResults]
    by_key: dict[tuple[int, int], RecordedResults]
    reference_key: tuple[int, int] | None
    reference_index: int | None
    xy: np.ndarray | None
    ids: np.ndarray | None
    rig: StereoCalibration | None = None
    rig_from: str | None = None


def _replay(request: _Request, dask: _OnDask | None = None) -> ReplayReport:
    """``replay``: sequential (``dask`` None) or on the Dask cluster of ``dask``."""
    path = request.path
    with reader_notes() as notes:
        recorded, tracking, report = _read_recording(request, notes, dask.worker_notes if dask is not None else [])
        rebuild = request.point_options.given or recorded.xy is None
        points = _points(request, recorded, tracking, rebuild)
        config = _session_config(request, tracking, recorded)
        point_ids: list[np.ndarray] = []          # filled once the session has its points
        served: list[Any] = []                    # the session (a parallel one holds the worker-formatted rows)
        comparison = _Comparison(report, recorded.by_key, recorded.xy)
        sinks = [comparison] + _output_sinks(request, report, point_ids, served, parallel=dask is not None)
        frames = _recorded_frames(path, recorded, request.all_frames)
        make_session = _session_maker(request, recorded, dask, point_ids)
        started = time.perf_counter()
        with make_session(config, source=frames, points=points, sinks=sinks) as session:
            served.append(session)
            _prepare(session, request, recorded, rebuild)
            point_ids.append(np.arange(len(session.points), dtype=np.uint32) if rebuild or recorded.ids is None
                             else recorded.ids)
            session.start()
            session.run()
            if dask is not None:
                report.parallel = session.finish_parallel()    # type: ignore[attr-defined]  # a ParallelSession
                report.parallel.where = dask.where
        report.strain = session.strain.summary() if session.strain is not None else None
        report.force = session.load_stage.summary() if session.load_stage is not None else None
        floor = session.preparation.noise_floor
        report.noise_floor = floor.summary() if floor is not None else None
        if session.source_error is not None:
            raise session.source_error
        report.seconds = time.perf_counter() - started
        notes.extend(_frame_counts(report, frames, recorded, comparison))
        notes.extend(_stereo_report(report, frames, recorded))
    report.notes = list(notes)
    return report


def _read_recording(request: _Request, notes: list[str],
                    worker_notes: list[str]) -> tuple[_Recorded, TrackingConfig, ReplayReport]:
    """The recording's results and parameters, the tracking options to replay with, and the report to fill.

    ValueError (one line): bad parameters, or no results to replay without ``all_frames``.
    """
    from livedic.acquire.recording.reader import Recording

    path, given = request.path, request.given
    metadata, session_note = read_session_or_note(path)
    recording = Recording(path)
    results = list(recording.results())
    params, recorded_params, param_notes = resolve_parameters(metadata, given, results[0].method if results else "")
    tracking = check_parameters(params, request.threads)
    notes.extend(param_notes)
    notes.extend(worker_notes)
    if session_note:
        notes.append(session_note)
    changed = [(key, recorded_params.get(key), params[key]) for key in METHOD_KEYS
               if given.get(key) is not None and recorded_params.get(key) != params[key]]
    report = ReplayReport(path=path, params=params, recorded_params=recorded_params, changed=changed,
                          all_frames=request.all_frames, recorded_frames=len(results),
                          recorded_version=str(metadata.get("software_version", "")), notes=notes,
                          truncated=recording.info.truncated)
    if not results and not request.all_frames:
        raise ValueError(f"{path} holds no tracking results (/dic/results) to replay: pass --all-frames to "
                         f"track every recorded frame from the first one")
    recorded = _recorded(metadata, results, notes)
    recorded.rig, recorded.rig_from = _stereo_rig(path, metadata, request.rig)
    return recorded, tracking, report


def _stereo_rig(path: str, metadata: dict[str, Any], given: StereoCalibration | None
                ) -> tuple[StereoCalibration | None, str | None]:
    """A stereo recording's rig and where it came from: ``given`` (``--calibration``), else the recorded one
    (metadata ``STEREO_KEY``); (None, None) for a one-camera recording.

    ValueError (one line): ``given`` for a one-camera recording, or a stereo recording without its rig.
    """
    stereo = metadata.get(STEREO_KEY)
    if not stereo:
        if given is not None:
            raise ValueError(f"--calibration holds a stereo rig's calibration (two cameras) but {path} was recorded "
                             f"with one camera: give that camera's own calibration")
        return None, None
    if given is not None:
        return given, "the calibration file given (--calibration)"
    document = stereo.get("calibration") if isinstance(stereo, dict) else None
    if not document:
        raise ValueError(f"{path} is a stereo recording without its rig's calibration: give it with "
                         f"--calibration RIG.json")
    try:
        rig = StereoCalibration.from_dict(document)
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{path}: the recorded rig calibration cannot be read ({error}): give it with "
                         f"--calibration RIG.json") from None
    return rig, f"the recorded rig, which came from {stereo.get('calibration_from') or 'an unnamed source'}"


def _stereo_report(report: ReplayReport, frames: RecordedFrames, recorded: _Recorded) -> list[str]:
    """A stereo replay's rig and pairing in the report (``report.stereo``) and a note for frames without partner."""
    if recorded.rig is None:
        return []
    counts = frames.pairing
    report.stereo = {"calibration_from": recorded.rig_from, "baseline_mm": recorded.rig.baseline_mm,
                     "angle_deg": recorded.rig.angle_deg, "mm_per_px": 1.0 / nominal_px_per_mm(recorded.rig),
                     "pairing": counts.as_dict() if counts is not None else None}
    if counts is None or not counts.pairs_dropped:
        return []
    return [f"{counts.dropped_from('left')} left and {counts.dropped_from('right')} right frame(s) have no frame "
            f"of the same index in the other view: dropped, never paired with another"]


def _recorded(metadata: dict[str, Any], results: list[RecordedResults], notes: list[str]) -> _Recorded:
    """The results by key, the reference frame and the recorded points (a note when the first results are not
    the reference frame's)."""
    by_key: dict[tuple[int, int], RecordedResults] = {}
    for result in results:
        by_key.setdefault((int(result.frame_index), int(result.timestamp_ns)), result)
    recorded = _Recorded(metadata, results, by_key, None, None, None, None)
    if results:
        first = results[0]
        recorded.xy = np.column_stack([np.asarray(first.x, dtype=np.float64), np.asarray(first.y, dtype=np.float64)])
        recorded.ids = np.asarray(first.point_id)
        if int(first.reference_frame_index) == int(first.frame_index):
            recorded.reference_key = (int(first.frame_index), int(first.timestamp_ns))
        else:
            recorded.reference_index = int(first.reference_frame_index)
            notes.append(f"the first recorded results are for frame {first.frame_index}, not for the reference "
                         f"frame {recorded.reference_index}: the replay tracks the reference frame first, as live")
    return recorded


def _points(request: _Request, recorded: _Recorded, tracking: TrackingConfig,
            rebuild: bool) -> np.ndarray | Callable[[np.ndarray], np.ndarray] | None:
    """The session's points: the recorded ones, or a function building them on the reference image."""
    if not rebuild:
        return recorded.xy

    def points(image: np.ndarray) -> np.ndarray:
        return build_replay_points(image, recorded.metadata, tracking.subset, request.point_options, recorded.xy)
    return points


def _session_config(request: _Request, tracking: TrackingConfig, recorded: _Recorded) -> SessionConfig:
    """The session ``livedic run`` would run on these frames: blocking queue (nothing dropped), no warm-up; a
    stereo recording's rig as its calibration."""
    metadata = recorded.metadata
    stress = request.stress
    force: dict[str, Any] = {} if stress is None else {"load": stress.load, "load_offset": stress.offset_s,
                                       "area_mm2": stress.area_mm2}
    return SessionConfig(source=f"mcap:{request.path}", tracking=tracking, threads=request.threads, drop="block",
                         warm_up=False, command="livedic replay",
                         strain=StrainConfig.from_metadata(metadata, **(request.strain or {})),
                         static_frames=int(metadata.get(STATIC_FRAMES_KEY) or 0), rig=recorded.rig, **force)


def _output_sinks(request: _Request, report: ReplayReport, point_ids: list[np.ndarray],
                  served: list[Any], parallel: bool) -> list[FunctionSink]:
    """The sinks after the comparison: ``on_result``, ``on_rows`` and the progress (each required: a failure
    there ends the replay with its error)."""
    sinks = []
    on_result, on_rows, progress, stress = request.on_result, request.on_rows, request.progress, request.stress
    if on_result is not None:
        sinks.append(FunctionSink(lambda result, stats: on_result(result.frame, result.measurement, point_ids[0],
                                                                  result.strain),
                                  "output", required=True))
    if on_rows is not None:
        def rows(result: FrameResult, stats: SessionStats) -> None:
            frame: Any = result.frame
            session = served[0]
            frame_table = session.rows_of(frame) if parallel else None
            if frame_table is None:
                frame_table = frame_rows(frame.index, frame.timestamp_ns, point_ids[0],
                                         cast("Measurement", result.measurement), cast("StrainField", result.strain),
                                         session.strain)
            if stress is not None:
                frame_table = frame_table.with_force(result.force_N, result.stress_MPa)
            on_rows(frame_table)
        sinks.append(FunctionSink(rows, "output", required=True))
    if progress is not None:
        sinks.append(FunctionSink(lambda result, stats: progress(report.frames), "progress", required=True))
    return sinks


def _recorded_frames(path: str, recorded: _Recorded, all_frames: bool) -> RecordedFrames:
    """The frames to track, read from the recording at ``path`` (a stereo one's as pairs)."""
    from livedic.acquire.recording.source import McapPairs, McapSource
    source = McapPairs(path) if recorded.rig is not None else McapSource(path)
    return RecordedFrames(source, recorded.by_key, recorded.reference_key, recorded.reference_index,
                          all_frames)


def _session_maker(request: _Request, recorded: _Recorded, dask: _OnDask | None,
                   point_ids: list[np.ndarray]) -> Callable[..., Session]:
    """``Session``, or the parallel session measuring on ``dask``'s cluster."""
    if dask is None:
        return Session
    from livedic.stream.replay.parallel_replay import ParallelSession
    on_rows = request.on_rows
    return partial(ParallelSession, client=dask.client, frames_again=_recorded_frames(request.path, recorded,
                                                                                      request.all_frames),
                   recorded=recorded.by_key, in_flight=dask.in_flight, shared_path=dask.shared_path,
                   point_ids=point_ids,
                   rows=None if on_rows is None else "csv" if getattr(on_rows, "csv_text", False) else "columns")


def _prepare(session: Session, request: _Request, recorded: _Recorded, rebuild: bool) -> None:
    """``session.prepare()``, its refusals worded for the replay (ValueError, one line)."""
    try:
        session.prepare()
    except NoFrame:
        reference = recorded.reference_key[0] if recorded.reference_key else recorded.reference_index
        what = f"reference frame {reference}" if recorded.results else "frame"
        raise ValueError(f"{request.path} holds no image of the {what} (/camera/image): nothing to replay") from None
    except ExtensometerOffPoints as error:
        if not rebuild or request.strain:
            raise
        raise ValueError(f"the recording's {error.name} extensometer does not fit the points asked for "
                         f"({error}): give --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2 to "
                         f"place extensometers on them") from None


def _frame_counts(report: ReplayReport, frames: RecordedFrames, recorded: _Recorded,
                  comparison: _Comparison) -> list[str]:
    """The report's counts of frames not replayed, and a note for each kind."""
    notes = []
    report.skipped_before_reference = frames.skipped_before_reference
    report.missing_frames = len(recorded.by_key) - len(comparison.seen)
    if report.missing_frames:
        notes.append(f"{report.missing_frames} recorded result set(s) have no image in the file and were "
                     f"not replayed")
    if report.skipped_before_reference:
        notes.append(f"{report.skipped_before_reference} frame(s) recorded before the reference frame were "
                     f"skipped")
    return notes


class RecordedFrames:
    """The frames of a recording that a replay tracks, from its ``McapSource``.

    The first is the reference frame (``reference_key``: (index, timestamp) or
    ``reference_index``; frames before it are skipped and counted); then, unless
    ``all_frames``, only the frames with recorded results (``recorded``, keyed by
    (index, timestamp)), in the recorded order: what the live run tracked.
    """

    def __init__(self, source: McapSource | McapPairs, recorded: Mapping[tuple[int, int], RecordedResults],
                 reference_key: tuple[int, int] | None, reference_index: int | None, all_frames: bool) -> None:
        self.source = source
        self.recorded = recorded
        self.reference_key = reference_key
        self.reference_index = reference_index
        self.all_frames = all_frames
        self.skipped_before_reference = 0

    def __iter__(self) -> Iterator[Frame]:
        started = False
        for frame in self.source:
            key = (int(frame.index), int(frame.timestamp_ns))
            if not started:
                if (self.reference_key is not None and key != self.reference_key) or \
                        (self.reference_index is not None and key[0] != self.reference_index):
                    self.skipped_before_reference += 1
                    continue
                started = True
            elif not self.all_frames and key not in self.recorded:
                continue
            yield frame

    @property
    def settings(self) -> dict[str, Any]:
        return self.source.settings

    @property
    def stereo(self) -> bool:
        """Pairs (``McapPairs``): the session tracks them in stereo."""
        return bool(getattr(self.source, "stereo", False))

    @property
    def pairing(self) -> PairingCounts | None:
        """A stereo recording's pairing counts (``McapPairs.counts``), None for one camera."""
        return getattr(self.source, "counts", None)

    def close(self) -> None:
        self.source.close()
