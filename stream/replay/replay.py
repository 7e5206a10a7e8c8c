"""``livedic replay``: re-run tracking offline on a recording's frames.

``livedic replay FILE.mcap [-o OUT.csv | -o OUT.parquet] [method options] [--all-frames]``

The recorded frames are tracked again by the session ``livedic run`` runs
(``stream.session.session.Session``: the recorded frames -> a blocking queue, nothing
dropped -> the tracker -> the comparison with the recording, the CSV rows and
the progress line), its ``TrackingConfig`` built from the recording's metadata
and the options given. Every option that is not given is taken from the
recording's session metadata (``subset``, ``search``, ``subpixel``, ``seed_radius``,
``refind_radius``, ``refind_zncc``, ``seed``; the point grid from ``roi``, ``step``,
``n_points_wanted``, ``p0``), so with no options the replay repeats the live run.

Which frames are tracked matters for exactness. A live run may drop frames when
the tracker falls behind, and each frame starts from the result of the previous
*processed* frame; so by default the replay tracks exactly the frames that have
recorded results (``/dic/results``), in the recorded order, against the recorded
reference frame, with the recorded points (the ``x, y`` of the results). With
the recorded parameters its ``u, v, zncc, ok`` are then bit-for-bit the recorded
ones. ``--all-frames`` tracks every recorded frame from the reference on, also
those the live run dropped (the numbers then differ where frames were dropped, as
the seeds differ). Changed parameters keep the recorded frame set unless
``--all-frames`` is given; point options (``--roi``, ``--points``, ``--step``,
``--n-points``, ``--p0``) rebuild the points on the reference frame as ``run`` does.

The output CSV (``-o``, default stdout) is in long format, one row per frame and
point: ``frame,timestamp_ns,point_id,x,y,u,v,zncc,ok`` then ``status`` and, for
first-order sub-pixel methods, ``ux,uy,vx,vy,iterations``, then the strain ``exx,eyy,exy``
recomputed on the replayed displacements (``stream.stages.strain``; NaN where a point has none); numbers at full
precision (they read back as the same float64). ``-o OUT.parquet`` writes the same columns as a Parquet
file instead (typed: integers int64, ``ok`` bool, the rest float64 with NaN; ``stream.replay.rows``);
any other suffix is refused. The output is written under a temporary name and renamed into place
when the replay is complete: an error or Ctrl-C leaves no file. At the end a line on stderr says
how the replay compares with the recording (``ReplayReport.agreement``, an
``Agreement``):

- ``EXACT``: bit for bit, ``replay matches the recording exactly: 300 frames x 1059 points``.
  This is what a replay on the machine (and livedic version) that recorded the
  session gives.
- ``WITHIN_ROUNDING``: not bit for bit, but every u and v within
  ``ROUNDING_TOLERANCE_PX`` (1e-4 px) and every ZNCC within ``ROUNDING_TOLERANCE_ZNCC`` (2e-5)
  of the recorded ones, with the same points ok and the same NaN: ``replay agrees
  with the recording within floating-point rounding (max 1.8e-06 px <= 1e-4 px
  tolerance)``. The compiled kernels round differently on another CPU (vector
  width, fused multiply-add, numba/LLVM version), so this is what another machine
  gives.
- ``DIFFERS``: anything more, with the sizes of the differences. A point that is
  ok on one side and not on the other counts as a real difference, even where
  rounding pushed its ZNCC or convergence test across a threshold: it changes
  what the user gets (a value or a gap), so it is reported, not excused.
- ``NOT_COMPARED``: nothing to compare (other points, no recorded results).

Truncated recordings (crash, kill, disk full) are replayed on what can be recovered.

In parallel (``--workers N``: a local Dask cluster of N worker processes; ``--cluster
ADDRESS``: an existing Dask scheduler) every frame is measured on its own, started from
the recorded result of the frame before it (``stream.replay.parallel_replay``), and the results
come back in frame order to the same session: the CSV, the comparison and its verdict are
the sequential replay's (bit for bit on the machine that recorded; within rounding of it
elsewhere). ``--shared-path`` lets the workers read the frames from the file instead of
receiving them. Reference updates and fractures are followed as sequentially (the frames
after one are measured against the tracker that frame left).
"""

import os
import time

import numpy as np

from livedic.dic.strain.extensometer import ExtensometerOffPoints
from livedic.stream.session.config import SessionConfig
from livedic.stream.replay.rows import frame_rows
from livedic.stream.session.session import NoFrame, Session
from livedic.stream.pipeline.sinks import FunctionSink
from livedic.stream.stages.strain import StrainConfig

from livedic.stream.export.notes import read_session_or_note, reader_notes
from livedic.stream.replay.agreement import ReplayReport, _Comparison
from livedic.stream.replay.parameters import METHOD_KEYS, check_parameters, resolve_parameters
from livedic.stream.replay.points import PointOptions, build_replay_points
# Re-exported: callers name them as replay's (stream.cli.replay, the tests).
from livedic.stream.replay.agreement import ROUNDING_TOLERANCE_PX, ROUNDING_TOLERANCE_ZNCC, Agreement  # noqa: F401


def replay(path, given=None, *, point_options=None, all_frames=False, on_result=None, progress=None,
           threads=1, strain=None, workers=None, cluster=None, in_flight=None, shared_path=None, on_rows=None,
           stress=None):
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

    Raises
    ------
    ValueError
        Bad parameters, or a recording that is missing, not MCAP, not livedic,
        corrupt, or holds nothing to replay (``RecordingError`` is a ValueError); in parallel
        also ``ClusterError`` (no scheduler at ``cluster``, no worker, livedic missing there) and
        a recording without results to seed the frames from (``--all-frames``).
    SourceError
        The frames cannot be read (``RecordingSourceError``).
    """
    path = os.fspath(path)
    point_options = point_options or PointOptions()
    point_options.check()
    if workers is not None or cluster is not None:
        from livedic.stream.replay.parallel_replay import check_cluster_address, check_worker_count, check_workers, dask_client
        if workers is not None:
            check_worker_count(workers)
        if cluster is not None:
            check_cluster_address(cluster)          # its form, before the recording is read (one line otherwise)
        _check_parallel_input(path, given, all_frames, threads)
        if shared_path == "":
            from livedic.acquire.recording.source import FrameReader
            shared_path = os.path.abspath(path)
            FrameReader(shared_path)                # indexed? (one line otherwise)
        with dask_client(workers, cluster) as client:
            worker_notes = check_workers(client)
            return _replay(path, given, point_options, all_frames, on_result, progress, threads, strain, on_rows,
                           stress=stress, client=client, in_flight=in_flight, shared_path=shared_path,
                           where=f"the Dask scheduler at {cluster}" if cluster is not None
                           else f"a local Dask cluster of {workers} worker process(es)", worker_notes=worker_notes)
    return _replay(path, given, point_options, all_frames, on_result, progress, threads, strain, on_rows,
                   stress=stress)


def _check_parallel_input(path, given, all_frames, threads):
    """What the parallel replay refuses before any cluster starts (one line, as the sequential replay words
    it, or its own): bad parameters, nothing to seed the frames from."""
    from livedic.acquire.recording.reader import Recording
    with reader_notes():                   # the replay itself says what the reader notes (a truncated file)
        metadata, _ = read_session_or_note(path)
        first = next(iter(Recording(path).results()), None)
    params, _, _ = resolve_parameters(metadata, given or {}, first.method if first is not None else "")
    check_parameters(params, threads)
    if first is None and all_frames:
        raise ValueError(f"{path} holds no tracking results to seed the frames from: replay it without "
                         f"--workers/--cluster")


def _replay(path, given, point_options, all_frames, on_result, progress, threads, strain, on_rows=None, *,
            stress=None, client=None, in_flight=None, shared_path=None, where=None, worker_notes=()):
    """``replay``: sequential (``client`` None) or on the Dask ``client``."""
    from livedic.acquire.recording.reader import Recording
    from livedic.acquire.recording.source import McapSource

    with reader_notes() as notes:
        metadata, session_note = read_session_or_note(path)
        recording = Recording(path)
        results = list(recording.results())
        params, recorded_params, param_notes = resolve_parameters(
            metadata, given or {}, results[0].method if results else "")
        tracking = check_parameters(params, threads)
        notes.extend(param_notes)
        notes.extend(worker_notes)
        if session_note:
            notes.append(session_note)
        changed = [(key, recorded_params.get(key), params[key]) for key in METHOD_KEYS
                   if (given or {}).get(key) is not None and recorded_params.get(key) != params[key]]
        report = ReplayReport(path=path, params=params, recorded_params=recorded_params, changed=changed,
                              all_frames=all_frames, recorded_frames=len(results),
                              recorded_version=str(metadata.get("software_version", "")), notes=notes,
                              truncated=recording.info.truncated)
        if not results and not all_frames:
            raise ValueError(f"{path} holds no tracking results (/dic/results) to replay: pass --all-frames to "
                             f"track every recorded frame from the first one")
        recorded = {}
        for result in results:
            recorded.setdefault((int(result.frame_index), int(result.timestamp_ns)), result)
        reference_key = reference_index = None
        recorded_xy = recorded_ids = None
        if results:
            first = results[0]
            recorded_xy = np.column_stack([np.asarray(first.x, dtype=np.float64),
                                           np.asarray(first.y, dtype=np.float64)])
            recorded_ids = np.asarray(first.point_id)
            if int(first.reference_frame_index) == int(first.frame_index):
                reference_key = (int(first.frame_index), int(first.timestamp_ns))
            else:
                reference_index = int(first.reference_frame_index)
                notes.append(f"the first recorded results are for frame {first.frame_index}, not for the reference "
                             f"frame {reference_index}: the replay tracks the reference frame first, as live")
        rebuild = point_options.given or recorded_xy is None
        if rebuild:
            def points(image):
                return build_replay_points(image, metadata, tracking.subset, point_options, recorded_xy)
        else:
            points = recorded_xy
        # The session: the recorded frames -> a blocking queue (nothing dropped) -> tracker -> comparison,
        # rows out, progress (each required: a failure there ends the replay with its error).
        force = {} if stress is None else {"load": stress.load, "load_offset": stress.offset_s,
                                           "area_mm2": stress.area_mm2}
        config = SessionConfig(source=f"mcap:{path}", tracking=tracking, threads=threads, drop="block",
                               warm_up=False, command="livedic replay",
                               strain=StrainConfig.from_metadata(metadata, **(strain or {})), **force)
        point_ids = []
        comparison = _Comparison(report, recorded, recorded_xy)
        sinks = [comparison]
        if on_result is not None:
            sinks.append(FunctionSink(lambda result, stats: on_result(result.frame, result.measurement, point_ids[0],
                                                                      result.strain),
                                      "output", required=True))
        served = []                   # the parallel session (its tracker holds the worker-formatted lines)
        if on_rows is not None:
            def rows(result, stats):
                frame_table = served[0].rows_of(result.frame) if served else None
                if frame_table is None:
                    frame_table = frame_rows(result.frame.index, result.frame.timestamp_ns, point_ids[0],
                                             result.measurement, result.strain)
                if stress is not None:
                    frame_table = frame_table.with_force(result.force_N, result.stress_MPa)
                on_rows(frame_table)
            sinks.append(FunctionSink(rows, "output", required=True))
        if progress is not None:
            sinks.append(FunctionSink(lambda result, stats: progress(report.frames), "progress", required=True))
        frames = RecordedFrames(McapSource(path), recorded, reference_key, reference_index, all_frames)
        if client is None:
            make_session = Session
        else:
            from functools import partial

            from livedic.stream.replay.parallel_replay import ParallelSession
            again = RecordedFrames(McapSource(path), recorded, reference_key, reference_index, all_frames)
            make_session = partial(ParallelSession, client=client, frames_again=again, recorded=recorded,
                                   in_flight=in_flight, shared_path=shared_path, point_ids=point_ids,
                                   rows=None if on_rows is None
                                   else "csv" if getattr(on_rows, "csv_text", False) else "columns")
        started = time.perf_counter()
        with make_session(config, source=frames, points=points, sinks=sinks) as session:
            if client is not None:
                served.append(session)
            try:
                session.prepare()
            except NoFrame:
                what = f"reference frame {reference_key[0] if reference_key else reference_index}" if results \
                    else "frame"
                raise ValueError(f"{path} holds no image of the {what} (/camera/image): nothing to replay") from None
            except ExtensometerOffPoints as error:
                if not rebuild or strain:
                    raise
                raise ValueError(f"the recording's {error.name} extensometer does not fit the points asked for "
                                 f"({error}): give --gauge-length L[,W] or --extensometer NAME=x1,y1,x2,y2 to "
                                 f"place extensometers on them") from None
            point_ids.append(np.arange(len(session.points), dtype=np.uint32) if rebuild else recorded_ids)
            session.start()
            session.run()
            if client is not None:
                report.parallel = session.finish_parallel()
                report.parallel.where = where
        report.strain = session.strain.summary() if session.strain is not None else None
        report.force = session.load_stage.summary() if session.load_stage is not None else None
        if session.source_error is not None:
            raise session.source_error
        report.seconds = time.perf_counter() - started
        report.skipped_before_reference = frames.skipped_before_reference
        report.missing_frames = len(recorded) - len(comparison.seen)
        if report.missing_frames:
            notes.append(f"{report.missing_frames} recorded result set(s) have no image in the file and were "
                         f"not replayed")
        if report.skipped_before_reference:
            notes.append(f"{report.skipped_before_reference} frame(s) recorded before the reference frame were "
                         f"skipped")
    report.notes = list(notes)
    return report


class RecordedFrames:
    """The frames of a recording that a replay tracks, from its ``McapSource``.

    The first is the reference frame (``reference_key``: (index, timestamp) or
    ``reference_index``; frames before it are skipped and counted); then, unless
    ``all_frames``, only the frames with recorded results (``recorded``, keyed by
    (index, timestamp)), in the recorded order: what the live run tracked.
    """

    def __init__(self, source, recorded, reference_key, reference_index, all_frames):
        self.source = source
        self.recorded = recorded
        self.reference_key = reference_key
        self.reference_index = reference_index
        self.all_frames = all_frames
        self.skipped_before_reference = 0

    def __iter__(self):
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
    def settings(self):
        return self.source.settings

    def close(self):
        self.source.close()
