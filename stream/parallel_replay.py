"""``livedic replay --workers N`` / ``--cluster ADDRESS``: the replay's frames measured in parallel on Dask.

Why it can be parallel. A tracker measures every frame against the reference
(frame 0); what it carries from frame to frame is only where to start: the
previous frame's result and each point's last ok result (``dic.Tracker.resume``
names that state). A recording holds the result of every frame the live run
tracked, so each frame can be measured on its own, on any worker, by the same
``Tracker.track`` started from the recorded result of the frame tracked just
before it (and the last ok result of every point before that): IC-GN then starts
where the sequential replay starts, and with the recorded parameters it ends where
it ends. Frames without recorded results (``--all-frames``: frames the live run
dropped) and points that were not ok start from the last recorded result before
them: ``track``'s own coarse pass (the seeded integer search for doubtful points,
then the wide re-find search around the point's last good displacement or its
nearest good neighbour's) finds them, as it finds points after a jump live.
Rebuilt points (``--roi``, ``--step`` ...) start from the nearest recorded point.

The pipeline: the client reads the recorded frames in replay order and submits one
task per frame (the image as recorded, uint8/uint16, plus its seed; the reference
and the tracker settings go to every worker once, as one task's result that the
scheduler can compute again if its worker dies), at most
``in_flight`` ahead of the frame being written, so memory stays bounded on a
20,000-frame recording. Each worker keeps one ``dic.Tracker`` per replay (the
reference prepared once). The results come back to the replay's own session
(``stream.session.Session``: the same strain stage, comparison with the recording,
CSV rows and progress line as the sequential replay) in frame order: the session's
tracker (``ServedTracker``) hands it the next frame's result, checking that it is
the result of that very frame (position and key), so a frame is never lost,
duplicated or out of place. A worker that dies has its running and held tasks
re-run elsewhere by the scheduler (``distributed`` reassigns them; ``retries=``
re-runs a task that raised).

What it does not follow (yet). The sequential replay runs ``dic.KeyFrameTracker``:
it moves the reference to a key frame when ``--reference-update`` says so and stops
tracking the points across a crack once it detects a fracture; both change how every
later frame is measured. The parallel replay checks, frame by frame in order, with
the same ``UpdatePolicy.reason`` and ``dic.fracture.detect_fracture`` calls, that
neither would have happened, and stops with one line (``ParallelReplayLimit``, exit
2, no output written) where one would; a recording whose results show a reference
move or separated points is refused before any work. Recordings made with
``--reference-update never``, or ``auto`` where the reference never moved, without a
fracture, replay in parallel.

Equality with the sequential replay. With the recorded parameters, on the machine that
recorded, the tracker starts every frame from the state the sequential replay starts it
from, and the outputs are bit for bit the same (``tests/stream/test_replay_parallel.py``).
Elsewhere (the shipped sample, recorded on another CPU) the recorded starts differ from
the sequential replay's own by rounding: within 2e-6 px of it, the same points ok. Not
restored from a recording: the wide re-find search's back-off (``Tracker.resume``), which
the results do not show; a point lost for several frames (an occlusion) may be searched
for, and found, a frame earlier or later than sequentially, which the comparison then
reports (ok differs). Changed parameters (another subset, other points) start from the
recorded results as seeds: measured within 1e-5 px of the sequential replay.

What travels (measured by ``livedic bench replay``, 2-core machine): the image as
recorded (1.05 MB a frame at 1 MP 8-bit) and its seed (~110 B a point when some point
was lost, ~57 B otherwise); a batch of no-op tasks carrying a 1 MB image cost 8 ms a task,
3 ms with 64 kB. ``--shared-path`` sends only the frame's key, the workers reading the
image from the file (``acquire.mcap_replay.FrameReader``: one chunk through the index).
"""

import time
import uuid
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from livedic.dic.fracture import detect_fracture
from livedic.dic.key_frames import UpdatePolicy
from livedic.dic.neighbours import typical_spacing
from livedic.dic.quality import Gates
from livedic.dic.result import Measurement
from livedic.dic.status import NOT_IN_KEY_FRAME, SEPARATED
from livedic.dic.tracking import Tracker, last_good_after
from livedic.stream.replay_rows import frame_rows
from livedic.stream.session import Session

# Tasks submitted ahead of the frame being written, per worker thread: enough to keep every worker busy
# while one frame is late, few enough that a 5 MP recording does not pile up in memory (4 x 5 MB a worker).
IN_FLIGHT_PER_WORKER = 4
# A task that raises is run again this many times (a worker that dies is the scheduler's: its tasks are
# reassigned, up to distributed's allowed-failures).
TASK_RETRIES = 2
CONNECT_TIMEOUT_S = 10
# No dashboard; the scheduler's HTTP routes (health, metrics) on a free port, not 8787 (taken by a second cluster).
LOCAL_SCHEDULER_OPTIONS = {"dashboard_address": ":0"}


class ParallelReplayLimit(ValueError):
    """The parallel replay cannot give what the sequential one gives here (one line: where, why, what to do)."""


class ClusterError(ValueError):
    """No Dask cluster to run on (a bad ``--cluster`` address, a scheduler that does not answer)."""


# ----------------------------------------------------------------------------- the cluster

@contextmanager
def dask_client(workers=None, cluster=None, *, timeout_s=None):
    """A ``distributed.Client``: on a new LocalCluster of ``workers`` processes, or on the scheduler ``cluster``.

    The LocalCluster runs one thread per worker process (numba uses 1 thread per task, see ``measure_frame``),
    no dashboard; it is closed on exit. ``ClusterError`` (one line) when ``cluster`` cannot be reached.
    """
    import logging

    from distributed import Client, LocalCluster
    if cluster is not None:
        address = str(cluster)
        timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
        try:
            client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as error:
            raise ClusterError(f"--cluster {address}: no Dask scheduler answered there "
                               f"({type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}); "
                               f"start one with dask-scheduler, or use --workers N") from None
        try:
            yield client
        finally:
            client.close()
        return
    check_worker_count(workers)
    local = LocalCluster(n_workers=workers, processes=True, threads_per_worker=1, dashboard_address=None,
                         scheduler_kwargs=LOCAL_SCHEDULER_OPTIONS, silence_logs=logging.CRITICAL)
    try:
        client = Client(local, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
    finally:
        local.close()


def check_worker_count(workers):
    """ValueError (one line) unless ``workers`` is a positive integer (``--workers N``)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"--workers must be a positive integer, got {workers!r}")


def _worker_version():
    from livedic.acquire.mcap_io import software_version
    return software_version()


def check_workers(client, timeout_s=None):
    """The cluster's workers can run the replay: livedic importable on each (one line otherwise); returns
    notes (a worker with another livedic version than this process: its numbers may differ by rounding)."""
    from livedic.acquire.mcap_io import software_version
    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    try:
        client.wait_for_workers(1, timeout=timeout_s)
        versions = client.run(_worker_version)
    except (ImportError, AttributeError) as error:
        raise ClusterError(f"the Dask workers cannot run livedic ({type(error).__name__}: {error}): install it "
                           f"(the same version) where the workers run") from None
    except TimeoutError:
        raise ClusterError(f"the Dask scheduler has no worker (none joined within {timeout_s} s): start some "
                           f"with dask-worker ADDRESS") from None
    mine = software_version()
    others = sorted({version for version in versions.values() if version != mine})
    if others:
        return [f"Dask workers run livedic {', '.join(others)}, this process {mine}: their numbers may differ "
                f"from this version's by rounding"]
    return []


def cluster_threads(client):
    """Worker threads of the cluster now (at least 1)."""
    return max(1, sum(client.nthreads().values()))


# ----------------------------------------------------------------------------- the worker side

@dataclass(frozen=True)
class ReplayJob:
    """What every worker needs once per replay: the reference, the points and the tracker settings."""
    token: str
    reference: np.ndarray
    points: np.ndarray
    tracker_options: dict
    threads: int = 1
    point_ids: np.ndarray = None          # with ``strain``: the CSV lines are formatted on the worker
    strain: object = None                 # the session's stream.strain.StrainStage (its compute)


@dataclass
class FrameMeasured:
    """A worker's answer for one frame (``position``: its place in the replay's frame order)."""
    position: int
    key: tuple
    measurement: Measurement
    refound: np.ndarray
    refind_attempts: int
    seconds: float
    header: list = None                   # the frame's CSV columns and lines (stream.replay_rows.frame_rows)
    lines: str = None
    rows_seconds: float = 0.0             # the time the worker spent on them (strain and formatting)


_TRACKERS = {}          # per worker process: job token -> Tracker (the reference prepared once)
_READERS = {}           # per worker process: recording path -> acquire.mcap_replay.FrameReader


@dataclass(frozen=True)
class FrameAt:
    """A frame for the worker to read itself from the recording at ``path`` (``--shared-path``)."""
    path: str
    index: int
    timestamp_ns: int


def _image_of(frame):
    """The image a task was given, or read from the shared recording (one reader per path and worker)."""
    if not isinstance(frame, FrameAt):
        return frame
    from livedic.acquire.mcap_replay import FrameReader
    reader = _READERS.get(frame.path)
    if reader is None:
        _READERS.clear()
        reader = _READERS[frame.path] = FrameReader(frame.path)
    return reader.image(frame.index, frame.timestamp_ns)


def tracker_options(tracking):
    """``dic.Tracker`` keyword arguments of a ``stream.config.TrackingConfig``: what ``TrackingConfig.tracker``
    gives its ``KeyFrameTracker`` for every inner tracker (the quality gates from ``min_zncc``)."""
    options = tracking.as_dict()
    options.pop("reference_update")
    options["gates"] = Gates(min_zncc=options.pop("min_zncc"))
    return options


def _the_job(job):
    return job


def _tracker_for(job):
    tracker = _TRACKERS.get(job.token)
    if tracker is None:
        _TRACKERS.clear()                   # one replay at a time per worker: free the previous reference
        tracker = Tracker(job.reference, job.points, **job.tracker_options)
        _TRACKERS[job.token] = tracker
    return tracker


def measure_frame(job, position, key, image, previous, last_good):
    """Measure one frame on a worker: the job's tracker resumed from the seed, then ``Tracker.track``.

    Parameters
    ----------
    job : ReplayJob
    position : int
        The frame's place in the replay's order (0: the reference).
    key : (int, int)
        Its (frame index, timestamp ns).
    image : ndarray (H, W) or FrameAt
        As recorded (uint8 or uint16), or where the worker reads it (``--shared-path``).
    previous, last_good
        ``Tracker.resume``'s arguments (None, None for the reference frame).
    """
    import numba
    if numba.get_num_threads() != job.threads:
        numba.set_num_threads(job.threads)
    started = time.perf_counter()
    tracker = _tracker_for(job)
    image = _image_of(image)
    tracker.resume(previous, last_good=last_good)
    measurement = tracker.track(image)
    seconds = time.perf_counter() - started
    header = lines = None
    if job.strain is not None:
        strain, _ = job.strain.compute(measurement.u, measurement.v, measurement.ok)
        header, lines = frame_rows(key[0], key[1], job.point_ids, measurement, strain)
    return FrameMeasured(position=position, key=key, measurement=measurement, refound=tracker.last_refound.copy(),
                         refind_attempts=tracker.last_refind_attempts, seconds=seconds, header=header, lines=lines,
                         rows_seconds=time.perf_counter() - started - seconds)


# ----------------------------------------------------------------------------- seeds

_SEED_FIELDS = ("u", "v", "zncc", "ok", "ux", "uy", "vx", "vy")


def _slim(measurement, take=None):
    """The fields ``Tracker.resume`` reads (float64/bool), for the points ``take`` (None: all)."""
    def pick(name, dtype):
        values = getattr(measurement, name)
        if values is None:
            return None
        values = np.asarray(values, dtype=dtype)
        return np.ascontiguousarray(values if take is None else values[take])
    ok = pick("ok", bool)
    empty = np.zeros(0)
    return Measurement(x=empty, y=empty, u=pick("u", np.float64), v=pick("v", np.float64),
                       zncc=pick("zncc", np.float64), ok=ok, status=np.zeros(0, dtype=np.int8),
                       **{name: pick(name, np.float64) for name in ("ux", "uy", "vx", "vy")})


def nearest_recorded(x, y, recorded_x, recorded_y):
    """For each point (x, y), the index of the nearest recorded point (chunked: no N x M matrix at once)."""
    out = np.empty(len(x), dtype=np.int64)
    rx, ry = np.asarray(recorded_x, dtype=np.float64), np.asarray(recorded_y, dtype=np.float64)
    for start in range(0, len(x), 256):
        d2 = (x[start:start + 256, None] - rx[None, :]) ** 2 + (y[start:start + 256, None] - ry[None, :]) ** 2
        out[start:start + 256] = np.argmin(d2, axis=1)
    return out


class Seeds:
    """The start of each frame in replay order: the last recorded result before it and every point's last ok one.

    ``next(key)`` returns (previous, last_good) for the frame ``key`` = (index, timestamp) and then takes
    that frame's recorded result (if any) into account for the frames after it.
    """

    def __init__(self, recorded, x, y):
        self.recorded = recorded
        self.x, self.y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        self.previous = None
        self.last_good = None
        self._layouts = {}

    def _on_points(self, result):
        """``result`` on this replay's points: as it is when recorded on them, else from the nearest recorded."""
        m = result.measurement
        if len(m.x) == len(self.x) and np.array_equal(m.x, self.x) and np.array_equal(m.y, self.y):
            return _slim(m)
        layout = (len(m.x), np.asarray(m.x).tobytes(), np.asarray(m.y).tobytes())
        take = self._layouts.get(layout)
        if take is None:
            take = self._layouts[layout] = nearest_recorded(self.x, self.y, m.x, m.y)
        return _slim(m, take)

    def next(self, key):
        last_good = self.last_good
        if last_good is not None and not np.any(last_good["ever"] & ~self.previous.ok):
            last_good = None        # every point ever ok is ok in the previous frame: resume's default is the same
        seed = (self.previous, last_good)
        result = self.recorded.get(key)
        if result is not None:
            self.previous = self._on_points(result)
            self.last_good = last_good_after(self.last_good, self.previous)
        return seed


def recorded_limits(results, *, moves=True):
    """Why a recording cannot be replayed in parallel, from its results, or None.

    A fracture (points ``SEPARATED``) and, with ``moves`` (the replay's policy may move the reference), a
    reference move (``reference_frame_index`` changes, points ``NOT_IN_KEY_FRAME``).
    """
    if not results:
        return None
    first_reference = int(results[0].reference_frame_index)
    for result in results:
        if moves and int(result.reference_frame_index) != first_reference:
            return (f"the reference moved to frame {result.reference_frame_index} (a key frame) in the recording, "
                    f"and the parallel replay does not follow reference updates yet")
        status = None if result.status is None else np.asarray(result.status)
        if status is None:
            continue
        if np.any(status == SEPARATED):
            return (f"points are separated by a fracture from frame {result.frame_index} on in the recording, "
                    f"and the parallel replay does not follow fractures yet")
        if moves and np.any(status == NOT_IN_KEY_FRAME):
            return (f"points were left out of a key frame at frame {result.frame_index} in the recording, "
                    f"and the parallel replay does not follow reference updates yet")
    return None


# ----------------------------------------------------------------------------- the client side

class OrderedResults:
    """Submit the frames of ``frames`` to ``client`` (at most ``in_flight`` ahead) and hand their results back
    in order, each exactly once (``take(position, key)`` checks both)."""

    def __init__(self, client, job, frames, seeds, in_flight, shared_path=None):
        self.client = client
        # A task, not Client.scatter: the scheduler keeps what it was made from, so a worker that dies holding
        # the only copy costs a recomputation, not the replay (scattered data would be lost with it).
        self.job_future = client.submit(_the_job, job, key=f"livedic-replay-job-{job.token}", pure=False)
        self.token = job.token
        self.frames = iter(frames)
        self.seeds = seeds
        self.in_flight = max(1, int(in_flight))
        self.pending = {}            # position -> future
        self.submitted = 0
        self.taken = 0
        self.exhausted = False
        self.shared_path = shared_path
        self.image_bytes = 0         # what the frames weighed on the wire (their images; 0 when workers read them)
        self.seed_bytes = 0
        self.wait_seconds = 0.0      # the client blocked on the next result (the rest of its time is its own work)

    def _submit_more(self):
        while not self.exhausted and self.submitted < self.taken + self.in_flight:
            frame = next(self.frames, None)
            if frame is None:
                self.exhausted = True
                return
            key = (int(frame.index), int(frame.timestamp_ns))
            previous, last_good = self.seeds.next(key)
            if self.shared_path is None:
                image = np.ascontiguousarray(frame.image)
                self.image_bytes += image.nbytes
            else:
                image = FrameAt(self.shared_path, *key)
            position = self.submitted
            self.seed_bytes += _nbytes(previous) + _nbytes(last_good)
            self.pending[position] = self.client.submit(
                measure_frame, self.job_future, position, key, image, previous, last_good,
                key=f"livedic-replay-frame-{self.token}-{position}", retries=TASK_RETRIES, pure=False)
            self.submitted += 1

    def take(self, position, key):
        """The result of the frame at ``position`` (0 first), which must be the frame ``key``."""
        if position != self.taken:
            raise RuntimeError(f"parallel replay: frame at position {position} asked for, {self.taken} expected")
        self._submit_more()
        future = self.pending.pop(position, None)
        if future is None:
            raise RuntimeError(f"parallel replay: no task for the frame at position {position} (frame {key[0]}): "
                               f"the session and the submitted frames disagree")
        started = time.perf_counter()
        try:
            answer = future.result()
        except ValueError as error:             # RecordingError: a worker could not read the shared recording
            if self.shared_path is None:
                raise
            raise ValueError(f"a worker could not read frame {key[0]} from {self.shared_path} ({error}); "
                             f"--shared-path must name the recording as every worker sees it") from None
        self.wait_seconds += time.perf_counter() - started
        future.release()
        if answer.position != position or tuple(answer.key) != tuple(key):
            raise RuntimeError(f"parallel replay: the result for position {position} is frame {answer.key[0]} "
                               f"at position {answer.position}, not frame {key[0]}")
        self.taken += 1
        self._submit_more()
        return answer

    def check_complete(self):
        """RuntimeError unless every submitted frame's result was taken once and no frame is left unsent."""
        if self.pending or not self.exhausted and next(self.frames, None) is not None:
            raise RuntimeError(f"parallel replay: {len(self.pending)} frame result(s) submitted but not written "
                               f"(written {self.taken} of {self.submitted})")

    def cancel(self):
        for future in self.pending.values():
            future.cancel()
        self.pending.clear()


def _nbytes(value):
    if value is None:
        return 0
    arrays = value.values() if isinstance(value, dict) else (getattr(value, name) for name in _SEED_FIELDS)
    return sum(a.nbytes for a in arrays if a is not None)


class ServedTracker:
    """What the replay session tracks with: each frame's result measured on the cluster, in order.

    It stands in the session for the ``KeyFrameTracker`` it wraps (built on the reference by the session, as
    sequentially: points, ``trackable``) and checks, with the calls ``KeyFrameTracker.track`` makes, that the
    sequential replay would neither have moved the reference nor detected a fracture at this frame
    (``ParallelReplayLimit`` otherwise).
    """

    def __init__(self, tracker, results, keys, policy, subset):
        self.tracker = tracker
        self.subset = int(subset)
        self.results = results
        self.keys = keys
        self.policy = policy
        self.frames_tracked = 0
        self.last_refound = np.zeros(tracker.n_points, dtype=bool)
        self.last_refind_attempts = 0
        self.last_seed_searches = 0
        self.last_update = None
        self.last_fracture = None
        self.compute_seconds = 0.0
        self.rows_seconds = 0.0
        self.last_answer = None
        self._previous = None
        n = tracker.n_points
        self._step = typical_spacing(np.column_stack([tracker.x, tracker.y])) if n > 1 else 1.0

    @property
    def n_points(self):
        return self.tracker.n_points

    @property
    def trackable(self):
        return self.tracker.trackable

    @property
    def window(self):
        return self.tracker.window

    @property
    def x(self):
        return self.tracker.x

    @property
    def y(self):
        return self.tracker.y

    def track(self, image):
        key = self.keys.popleft()
        answer = self.results.take(self.frames_tracked, key)
        m = answer.measurement
        self.frames_tracked += 1
        self.compute_seconds += answer.seconds
        self.rows_seconds += answer.rows_seconds
        self.last_refound = answer.refound
        self.last_refind_attempts = answer.refind_attempts
        self.last_answer = answer
        self._check_same_course(key, m)
        self._previous = (m.ok.copy(), m.u.copy(), m.v.copy())
        return m

    def _check_same_course(self, key, m):
        """``ParallelReplayLimit`` where ``KeyFrameTracker.track`` would detect a fracture or move the reference."""
        trackable = self.tracker.trackable
        if self._previous is not None and getattr(self.tracker, "detect_fractures", True):
            ok_before, u_before, v_before = self._previous
            fracture = detect_fracture(self.tracker.x, self.tracker.y, ok_before, m.ok, u_before, v_before, m.u, m.v,
                                       step=self._step, subset=self.subset, trackable=trackable)
            if fracture is not None:
                raise ParallelReplayLimit(
                    f"frame {key[0]}: the replay detects a fracture there, which the parallel replay does not "
                    f"follow yet: replay without --workers/--cluster")
        reason = self.policy.reason(self.frames_tracked, m, trackable)
        if reason is not None:
            raise ParallelReplayLimit(
                f"frame {key[0]}: the replay moves the reference there ({reason}; --reference-update "
                f"{self.policy}), which the parallel replay does not follow yet: replay without --workers/--cluster, "
                f"or with --reference-update never")


class KeyedFrames:
    """The session's frames (a ``RecordedFrames``) noting each key as it passes, for ``ServedTracker``."""

    def __init__(self, frames, keys):
        self.frames = frames
        self.keys = keys

    def __iter__(self):
        for frame in self.frames:
            self.keys.append((int(frame.index), int(frame.timestamp_ns)))
            yield frame

    @property
    def settings(self):
        return self.frames.settings

    def close(self):
        self.frames.close()


@dataclass
class ParallelStats:
    """How the parallel part went (``ReplayReport.parallel``)."""
    workers: int = 0
    where: str = ""
    frames: int = 0
    compute_seconds: float = 0.0          # summed over the tasks (the tracker's own time)
    rows_seconds: float = 0.0             # ... and the CSV lines' (strain and formatting on the workers)
    image_bytes: int = 0
    seed_bytes: int = 0
    shared_path: str = None               # where the workers read the frames (None: sent from the client)
    wait_seconds: float = 0.0             # the replaying process waiting for results (the rest: its own work)


class ParallelSession(Session):
    """The replay's ``Session`` with its frames measured on a Dask cluster (``ServedTracker``); same sinks."""

    def __init__(self, config, *, client, frames_again, recorded, in_flight=None, shared_path=None, point_ids=None,
                 rows=False, stats=None, **kwargs):
        self._keys = deque()
        source = kwargs.pop("source")
        super().__init__(config, source=KeyedFrames(source, self._keys), **kwargs)
        self._client = client
        self._frames_again = frames_again
        self._recorded = recorded
        self._in_flight = in_flight
        self._shared_path = shared_path
        self._point_ids = point_ids            # a list the replay fills with the point ids after ``prepare``
        self._rows = bool(rows)
        self.parallel = stats if stats is not None else ParallelStats()
        self.served = None
        self.results = None

    def _make_tracker(self, frame):
        tracker = super()._make_tracker(frame)
        tracking = self.config.tracking
        threads = cluster_threads(self._client)
        rows = self._rows and self.strain is not None
        job = ReplayJob(token=uuid.uuid4().hex, reference=np.ascontiguousarray(frame.image),
                        points=np.asarray(self.points, dtype=np.float64), tracker_options=tracker_options(tracking),
                        threads=1, point_ids=np.asarray(self._point_ids[0]) if rows else None,
                        strain=self.strain if rows else None)
        seeds = Seeds(self._recorded, tracker.x, tracker.y)
        in_flight = self._in_flight or IN_FLIGHT_PER_WORKER * threads
        self.results = OrderedResults(self._client, job, self._frames_again, seeds, in_flight, self._shared_path)
        self.served = ServedTracker(tracker, self.results, self._keys, UpdatePolicy.parse(tracking.reference_update),
                                    tracking.subset)
        self.parallel.workers = threads
        return self.served

    def rows_of(self, frame):
        """(header, lines) of ``frame``, the frame just tracked, as its worker formatted them."""
        answer = self.served.last_answer
        if answer is None or tuple(answer.key) != (int(frame.index), int(frame.timestamp_ns)) or answer.lines is None:
            raise RuntimeError(f"parallel replay: no formatted rows for frame {frame.index}")
        return answer.header, answer.lines

    def finish_parallel(self):
        """After ``run``: every frame taken once (RuntimeError otherwise); fills ``parallel``."""
        if self.results is None:
            return self.parallel
        self.results.check_complete()
        stats = self.parallel
        stats.frames = self.results.taken
        stats.compute_seconds = self.served.compute_seconds
        stats.rows_seconds = self.served.rows_seconds
        stats.image_bytes = self.results.image_bytes
        stats.seed_bytes = self.results.seed_bytes
        stats.shared_path = self.results.shared_path
        stats.wait_seconds = self.results.wait_seconds
        return stats

    def close(self):
        if self.results is not None:
            self.results.cancel()
        return super().close()
