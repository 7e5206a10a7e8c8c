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

import enum
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from livedic.dic.strain.extensometer import ExtensometerOffPoints
from livedic.stream.session.config import DEFAULT_POINTS, PointsConfig, SessionConfig, TrackingConfig
from livedic.stream.session.parsing import ROI_AUTO, ROI_FULL, parse_exclusion, parse_p0, parse_roi, read_mask
from livedic.stream.session.points import place_points, read_points_csv
from livedic.stream.replay.rows import frame_rows
from livedic.stream.session.session import NoFrame, Session
from livedic.stream.pipeline.sinks import FunctionSink
from livedic.stream.stages.strain import StrainConfig

from livedic.stream.export.export import read_session_or_note, reader_notes

# A replay on another machine agrees within these (see the module notes). Rounding differences of the
# compiled kernels moved u and v by 1.8e-6 px on the sample session (issue 8, another x86_64 CPU);
# 1e-4 px leaves room for that and is still 40x below the 8-bit rounding noise of a measurement
# (IC-GN ~4e-3 px SD).
ROUNDING_TOLERANCE_PX = 1e-4
# IC-GN forms ZNCC from per-row float32 sums (dic.subpixel.icgn), and its variance, sum g^2 - (sum g)^2 / n,
# cancels by the subset's mean^2 / var: one machine's rounding is k 2^-24 (mean^2 / var) / sqrt(side), k <= 4.4
# measured on reference frames (exact ZNCC 1: 953 subsets of the sample and of the simulated test to fracture;
# up to 2.5e-6 at mean^2 / var = 83, faded paint), and two CPUs differ by up to twice that (k <= 6.6 measured,
# 1.04e-6 on the sample). 2e-5 covers mean^2 / var up to 175 at subset 21: a grey-level SD down to 1/13 of the mean.
ROUNDING_TOLERANCE_ZNCC = 2e-5

METHOD_KEYS = TrackingConfig.keys()
_INT_KEYS = ("subset", "seed_radius", "refind_radius", "seed")
# What a recording made before a parameter existed did (replayed that way, not with today's default).
_BEFORE_KEY = {"reference_update": "never"}


# ----------------------------------------------------------------------------- parameters

def run_defaults():
    """The ``livedic run`` defaults of the method options (and ``n_points``): ``stream.session.config``'s."""
    return dict(TrackingConfig().as_dict(), n_points=DEFAULT_POINTS)


def _recorded_value(key, value):
    """``value`` as the type of ``key``, or None when it is missing or of the wrong type."""
    if isinstance(value, bool) or value is None:
        return None
    if key in _INT_KEYS:
        if isinstance(value, (int, np.integer)):
            return int(value)
        if isinstance(value, float) and value.is_integer():
            return int(value)
        return None
    if key in ("refind_zncc", "min_zncc"):
        return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None
    return value if isinstance(value, str) and value else None


def resolve_parameters(metadata, given, method_text=""):
    """(parameters used, recorded parameters found, notes).

    ``given``: the user's values (None = not given). A recorded value is taken
    from the session metadata, else for search/sub-pixel from the results' method
    text ("search+subpixel"), else ``livedic run``'s default (with a note).
    """
    defaults = run_defaults()
    from_method = {}
    if isinstance(method_text, str) and method_text.count("+") == 1:
        from_method = dict(zip(("search", "subpixel"), method_text.split("+")))
    used, recorded, notes = {}, {}, []
    for key in METHOD_KEYS:
        value = _recorded_value(key, metadata.get(key))
        if value is None:
            value = _recorded_value(key, from_method.get(key))
        if value is not None:
            recorded[key] = value
        if given.get(key) is not None:
            used[key] = given[key]
        elif value is not None:
            used[key] = value
        elif key in _BEFORE_KEY:
            used[key] = _BEFORE_KEY[key]          # recorded before the option existed: what it did then
        else:
            used[key] = defaults[key]
            notes.append(f"the recording does not say which {key} it used: using livedic run's default "
                         f"{defaults[key]}")
    return used, recorded, notes


def check_parameters(params, threads=None):
    """ValueError (one line, as ``livedic run`` words it) for a bad method parameter or thread count.

    The checks are ``stream.session.config``'s (``TrackingConfig``, ``SessionConfig``): returns the ``TrackingConfig``.
    """
    tracking = TrackingConfig(**{key: params[key] for key in METHOD_KEYS})
    if threads is not None:
        SessionConfig(threads=threads)
    return tracking


@dataclass
class PointOptions:
    """The user's point options (None = not given)."""
    roi: str = None
    points: str = None
    step: int = None
    n_points: int = None
    p0: str = None
    mask: str = None
    exclude: tuple = None

    @property
    def given(self):
        return any(value is not None for value in (self.roi, self.points, self.step, self.n_points, self.p0,
                                                   self.mask, self.exclude))

    @property
    def region_given(self):
        return any(value is not None for value in (self.roi, self.mask, self.exclude))

    def region(self):
        """``PointsConfig``'s region fields from what was given (``PointsConfig.region_from_args``)."""
        return PointsConfig.region_from_args(self)

    def check(self):
        """ValueError (one line) for a bad option: ``PointsConfig``'s checks, on what was given."""
        PointsConfig(step=self.step, n_points=self.n_points if self.n_points is not None else DEFAULT_POINTS,
                     p0=parse_p0(self.p0), **self.region())


def _list_of_numbers(value, count):
    if isinstance(value, (list, tuple)) and len(value) == count and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value):
        return [float(v) for v in value]
    return None


def recorded_region(metadata):
    """The region a recording's points were placed in, as ``PointsConfig`` fields (``roi``, ``exclude``).

    ``region`` (recordings since masks) says how; older ones give ``roi`` as X,Y,W,H or "full image".
    A recorded mask file is read again when it is still there, else its region's bounding box is used.
    """
    region = metadata.get("region") if isinstance(metadata.get("region"), dict) else {}
    exclude = tuple(parse_exclusion(text) for text in region.get("exclude") or ())
    placed_by = region.get("placed_by")
    if placed_by == "specimen":
        return {"roi": ROI_AUTO, "exclude": exclude}
    if placed_by == "given_region":
        fields = {"roi": parse_roi(region["roi"]) if region.get("roi") else None, "exclude": exclude}
        mask_file = region.get("mask")
        if mask_file and os.path.exists(mask_file):
            fields.update(mask=read_mask(mask_file), mask_file=mask_file)
        elif mask_file and fields["roi"] is None:
            bounds = _list_of_numbers(region.get("bounds"), 4)
            fields["roi"] = tuple(int(v) for v in bounds) if bounds else None
        return fields
    recorded_roi = _list_of_numbers(metadata.get("roi"), 4)
    if recorded_roi:
        return {"roi": tuple(int(v) for v in recorded_roi), "exclude": exclude}
    return {"roi": ROI_FULL, "exclude": exclude}


def replay_points_config(metadata, options, recorded_xy):
    """The points to rebuild (``PointsConfig``): the options given, the rest from the session metadata.

    What the user did not give comes from the session metadata (region, step, points
    wanted, P0); a recording made from a points file keeps its recorded points.
    """
    defaults = run_defaults()
    given_points = points_file = None
    if options.points is not None:
        given_points, points_file = read_points_csv(options.points), options.points
    elif not options.region_given and options.step is None and options.n_points is None \
            and metadata.get("points_file") not in (None, ""):
        if recorded_xy is None:
            raise ValueError(f"the recording tracked points from {metadata['points_file']}: give --points FILE.csv")
        given_points, points_file = recorded_xy, str(metadata["points_file"])
    region = options.region() if options.region_given else recorded_region(metadata)
    if options.step is not None:
        step = options.step
    elif options.region_given or options.n_points is not None:
        step = None
    else:
        step = _recorded_value("subset", metadata.get("step"))     # an int or None (then from n_points)
    n_points = options.n_points
    if n_points is None:
        n_points = _recorded_value("subset", metadata.get("n_points_wanted")) or defaults["n_points"]
    p0 = parse_p0(options.p0) if options.p0 is not None else _list_of_numbers(metadata.get("p0"), 2)
    return PointsConfig(points_file=points_file, xy=given_points, step=step, n_points=n_points, p0=p0, **region)


def build_replay_points(image, metadata, subset, options, recorded_xy):
    """Points (P0 first) for ``options`` given on the command line, as ``livedic run`` builds them.

    See ``replay_points_config``. A recording that does not give P0 as a point (older
    ones say "ROI centre") gets it placed on the reference ``image`` as ``livedic run``
    places it now.
    """
    wanted = replay_points_config(metadata, options, recorded_xy)
    return place_points(image, wanted, subset=subset).points


# ----------------------------------------------------------------------------- the replay

class Agreement(enum.Enum):
    """How a replay compares with the recording (see the module notes)."""
    EXACT = "exact"
    WITHIN_ROUNDING = "within floating-point rounding"
    DIFFERS = "differs"
    NOT_COMPARED = "not compared"


@dataclass
class ReplayReport:
    """What a replay did and how it compares with the recording."""
    path: str
    params: dict
    recorded_params: dict
    changed: list                    # (name, recorded value or None, value used)
    all_frames: bool = False
    frames: int = 0                  # frames tracked (the reference included)
    points: int = 0
    recorded_frames: int = 0         # result sets in the recording
    missing_frames: int = 0          # recorded result sets whose image is not in the file
    extra_frames: int = 0            # frames tracked without recorded results (--all-frames)
    skipped_before_reference: int = 0
    same_points: bool = False
    compared_frames: int = 0
    mismatched_frames: int = 0
    max_du: float = 0.0
    max_dv: float = 0.0
    max_dzncc: float = 0.0
    layout_differs: int = 0          # frames whose recorded points (count, x, y) differ from the replayed ones
    ok_differs: int = 0              # point-frames whose ok differs
    nan_differs: int = 0             # point-frames where one side is NaN and the other is not
    seconds: float = 0.0
    recorded_version: str = ""
    notes: list = field(default_factory=list)
    truncated: bool = False          # the recording ends early (crash, kill, disk full): the reader's RecordingInfo
    strain: dict = None              # stream.stages.strain.StrainStage.summary() of the replay (final extensometers)
    parallel: object = None          # stream.replay.parallel_replay.ParallelStats when measured on Dask (--workers, --cluster)
    force: dict = None               # stream.stages.force.LoadStage.summary() with --load

    @property
    def exact(self):
        """Every recorded frame that could be replayed is bit-for-bit equal (u, v, zncc, ok)."""
        return self.same_points and self.compared_frames > 0 and self.mismatched_frames == 0 \
            and self.compared_frames == self.recorded_frames - self.missing_frames

    @property
    def max_difference_px(self):
        """The largest |difference| in u or v over the compared point-frames (both finite)."""
        return max(self.max_du, self.max_dv)

    @property
    def agreement(self):
        """``Agreement``: exact, within floating-point rounding, differs, or not compared."""
        if self.recorded_frames == 0 or not self.same_points or self.compared_frames == 0:
            return Agreement.NOT_COMPARED
        if self.exact:
            return Agreement.EXACT
        if (self.compared_frames == self.recorded_frames - self.missing_frames and self.layout_differs == 0
                and self.ok_differs == 0 and self.nan_differs == 0
                and self.max_difference_px <= ROUNDING_TOLERANCE_PX
                and self.max_dzncc <= ROUNDING_TOLERANCE_ZNCC):
            return Agreement.WITHIN_ROUNDING
        return Agreement.DIFFERS

    def verdict(self):
        """One line for people: equal, equal within rounding, or by how much it differs."""
        changes = ", ".join(f"{name} {'?' if old is None else old} -> {new}" for name, old, new in self.changed)
        size = f"{self.compared_frames} frames x {self.points} points"
        agreement = self.agreement
        if agreement is Agreement.NOT_COMPARED:
            if self.recorded_frames == 0:
                return "the recording holds no results to compare with"
            if not self.same_points:
                return ("the points differ from the recorded ones (point options given): not compared with the "
                        "recording")
            return "no replayed frame has recorded results: not compared with the recording"
        if agreement is Agreement.EXACT:
            if changes:
                return f"replay with changed parameters ({changes}) still equals the recording exactly: {size}"
            return f"replay matches the recording exactly: {size}"
        if agreement is Agreement.WITHIN_ROUNDING:
            within = (f"within floating-point rounding (max {self.max_difference_px:.2g} px <= "
                      f"{_short(ROUNDING_TOLERANCE_PX)} px tolerance): {size}, the same points ok; bit-exact only "
                      f"on the machine that recorded it")
            if changes:
                return f"replay with changed parameters ({changes}) agrees with the recording {within}"
            return f"replay agrees with the recording {within}"
        text = (f"replay differs from the recording on {self.mismatched_frames} of {size}: max difference "
                f"{_g(self.max_du)} px in u, {_g(self.max_dv)} px in v, {_g(self.max_dzncc)} in zncc; "
                f"ok differs at {self.ok_differs} and NaN at {self.nan_differs} point-frames")
        if changes:
            return text + f" (changed parameters: {changes})"
        if self.all_frames and self.extra_frames:
            return text + (f" ({self.extra_frames} frames the live run dropped were tracked too, so later frames "
                           f"start from other seeds)")
        from livedic.acquire.recording.chunked_writer import software_version
        version = software_version()
        if self.recorded_version and self.recorded_version != version:
            return text + (f" with the recorded parameters: recorded with livedic {self.recorded_version}, "
                           f"replayed with {version}")
        return text + " with the recorded parameters"


def _short(value):
    """1e-4 rather than 0.0001 or 1e-04."""
    mantissa, exponent = f"{value:.0e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _g(value):
    return f"{value:.3g}"


def _same_bits(a, b):
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)
    return (a.view(np.uint64) == b.view(np.uint64)) | (np.isnan(a) & np.isnan(b))


def _compare(report, measurement, recorded):
    if len(recorded.u) != len(measurement.u) or not np.array_equal(recorded.x, measurement.x) \
            or not np.array_equal(recorded.y, measurement.y):
        report.compared_frames += 1
        report.mismatched_frames += 1
        report.layout_differs += 1
        return
    report.compared_frames += 1
    same = np.asarray(measurement.ok, dtype=bool) == np.asarray(recorded.ok, dtype=bool)
    report.ok_differs += int((~same).sum())
    for name in ("u", "v", "zncc"):
        a = np.asarray(getattr(measurement, name), dtype=np.float64)
        b = np.asarray(getattr(recorded, name), dtype=np.float64)
        same &= _same_bits(a, b)
        report.nan_differs += int((np.isnan(a) != np.isnan(b)).sum())
        both = np.isfinite(a) & np.isfinite(b)
        if both.any():
            attribute = {"u": "max_du", "v": "max_dv", "zncc": "max_dzncc"}[name]
            setattr(report, attribute, max(getattr(report, attribute), float(np.max(np.abs(a[both] - b[both])))))
    if not same.all():
        report.mismatched_frames += 1


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


class _Comparison:
    """The replay's sink that compares each tracked frame with its recorded results (fills the report)."""
    name = "comparison"
    required = True

    def __init__(self, report, recorded, recorded_xy):
        self.report = report
        self.recorded = recorded
        self.recorded_xy = recorded_xy
        self.seen = set()

    def __call__(self, result, stats):
        report = self.report
        m = result.measurement
        if result.is_reference:
            recorded_xy = self.recorded_xy
            report.points = stats.n_points
            report.same_points = recorded_xy is not None and recorded_xy.shape == (stats.n_points, 2) \
                and np.array_equal(recorded_xy[:, 0], m.x) and np.array_equal(recorded_xy[:, 1], m.y)
        report.frames += 1
        key = (int(result.frame.index), int(result.frame.timestamp_ns))
        match = self.recorded.get(key)
        if match is not None and key not in self.seen:
            self.seen.add(key)
            if report.same_points:
                _compare(report, m, match)
        else:
            report.extra_frames += 1
