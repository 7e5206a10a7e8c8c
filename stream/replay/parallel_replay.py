"""``livedic replay --workers N`` / ``--cluster ADDRESS``: the replay's frames measured in parallel on Dask.

Each frame is measured on its own, on any worker, by the same ``KeyFrameTracker.track`` as the
sequential replay: a copy of the tracker as the last reference move (or fracture) left it,
resumed from the recorded result of the frame tracked just before
(``dic.tracking.key_frames.KeyFrameTracker.resume``). A frame that moves the reference or breaks
the specimen starts a new segment; frames measured ahead against the earlier state are
submitted again. The client submits one task per frame (the image as recorded and its seed;
with ``--shared-path`` only the frame's key), at most ``in_flight`` ahead of the frame being
written, and hands the results in frame order to the replay's own
``stream.session.session.Session`` through a ``ServedTracker``.

Guarantees: every frame is written once, in order (a result is checked to be that very
frame's); a worker that dies has its tasks re-run elsewhere; the outputs (CSV rows, reference
moves, fractures, the comparison with the recording) are the sequential replay's, bit for bit
on the machine that recorded, within rounding elsewhere. Not restored from a recording: the
re-find search's back-off, so a point lost for several frames may be found a frame earlier or
later, which the comparison reports.

How it works, what travels and how it scales (measured): docs/guide/replay.md ("Replay on
many cores or machines (Dask)", "How the parallel replay works").
"""

import copy
import threading
import time
import uuid
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from livedic.dic.result import Measurement
from livedic.dic.status import SEPARATED
from livedic.dic.tracking import last_good_after
from livedic.stream.replay.rows import frame_rows
from livedic.stream.session.session import Session

# Tasks submitted ahead of the frame being written, per worker thread: enough to keep every worker busy
# while one frame is late, few enough that a 5 MP recording does not pile up in memory (4 x 5 MB a worker).
IN_FLIGHT_PER_WORKER = 4
# A task that raises is run again this many times (a worker that dies is the scheduler's: its tasks are
# reassigned, up to distributed's allowed-failures).
TASK_RETRIES = 2
CONNECT_TIMEOUT_S = 10
# The first contact with a --cluster scheduler: a scheduler that answers does so in milliseconds (a busy one within
# a second or two); nothing listening there (a wrong port, a stopped scheduler) must not keep the user 10 s.
FIRST_CONNECT_TIMEOUT_S = 4
# Schemes with a HOST:PORT location (inproc:// addresses name a process, and only that process can reach them).
_HOST_PORT_SCHEMES = ("tcp", "tls", "ucx", "ws", "wss")
# No dashboard; the scheduler's HTTP routes (health, metrics) on a free port, not 8787 (taken by a second cluster).
LOCAL_SCHEDULER_OPTIONS = {"dashboard_address": ":0"}


class ClusterError(ValueError):
    """No Dask cluster to run on (a bad ``--cluster`` address, a scheduler that does not answer)."""


# ----------------------------------------------------------------------------- the cluster

def check_cluster_address(address):
    """The ``--cluster`` address as ``distributed`` reads it; ``ClusterError`` (one line) when it cannot be one.

    Checks the form only, before any connection: a scheme ``distributed`` knows (``tcp://``, ``tls://``,
    ``inproc://``, ``ucx://``, ``ws://``, ``wss://``; none: its default, ``tcp``) and, except for ``inproc``,
    ``HOST:PORT`` with a port from 1 to 65535. A malformed address given to ``distributed.Client`` fails inside
    its constructor, which leaves a half-started client whose ``__del__`` prints a traceback 20 s later.
    """
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import backends
    address = str(address)
    shown = address if address.strip() else repr(address)
    usage = "give tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786, what `dask scheduler` prints) or HOST:PORT"
    if not address.strip():
        raise ClusterError(f"--cluster {shown}: no scheduler address; {usage}")
    scheme, location = parse_address(address)
    if scheme not in backends:
        raise ClusterError(f"--cluster {shown}: unknown scheme {scheme!r} (Dask knows {', '.join(sorted(backends))}); "
                           f"{usage}")
    if scheme in _HOST_PORT_SCHEMES:
        try:
            host, port = parse_host_port(location)
        except ValueError:
            raise ClusterError(f"--cluster {shown}: not HOST:PORT after {scheme}://; {usage}") from None
        if not host or not 1 <= port <= 65535:
            raise ClusterError(f"--cluster {shown}: " + ("no host" if not host else f"port {port} out of 1-65535")
                               + f"; {usage}")
    return address


def _first_contact(address, timeout_s):
    """Connect to the scheduler at ``address`` once and hang up (``ClusterError``, one line, when it does not
    answer within ``timeout_s`` or cannot be reached): the ``Client`` is made only where a scheduler answered."""
    import asyncio

    from distributed.comm import connect
    from distributed.security import Security

    async def contact():
        comm = await connect(address, timeout=timeout_s, **Security().get_connection_args("client"))
        await comm.close()

    outcome = {}

    def run():            # its own thread and event loop: replay() may be called from a running loop (Jupyter)
        try:
            asyncio.run(contact())
        except Exception as error:      # noqa: BLE001 - reported as one line below, whatever distributed raised
            outcome["error"] = error

    thread = threading.Thread(target=run, name="livedic-cluster-contact", daemon=True)
    thread.start()
    thread.join(timeout_s + 5)
    error = outcome.get("error")
    if thread.is_alive() or isinstance(error, (OSError, TimeoutError)):
        raise ClusterError(f"--cluster {address}: no Dask scheduler answered at {address} within {timeout_s:g} s; "
                           f"start one with `dask scheduler`, or use --workers N")
    if error is not None:           # TLS not configured, the ucx backend not installed, another process' inproc
        hint = "; ucx:// needs the distributed-ucxx package" if address.startswith("ucx://") else ""
        raise ClusterError(f"--cluster {address}: cannot connect ({_first_line(error)}){hint}")


def _first_line(error):
    text = str(error).strip()
    return f"{type(error).__name__}: {text.splitlines()[0]}" if text else type(error).__name__


@contextmanager
def dask_client(workers=None, cluster=None, *, timeout_s=None):
    """A ``distributed.Client``: on a new LocalCluster of ``workers`` processes, or on the scheduler ``cluster``.

    The LocalCluster runs one thread per worker process (numba uses 1 thread per task, see ``measure_frame``),
    no dashboard; it is closed on exit. ``ClusterError`` (one line) when ``cluster`` is not an address
    (``check_cluster_address``) or no scheduler answers there within ``FIRST_CONNECT_TIMEOUT_S``.
    """
    import logging

    from distributed import Client, LocalCluster
    if cluster is not None:
        address = check_cluster_address(cluster)
        _first_contact(address, FIRST_CONNECT_TIMEOUT_S)
        timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
        try:
            client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError) as error:        # the scheduler went away since (Client closed itself)
            raise ClusterError(f"--cluster {address}: the Dask scheduler stopped answering ({_first_line(error)}); "
                               f"start one with `dask scheduler`, or use --workers N") from None
        except ImportError as error:                    # its reply names what this process lacks (Client closed)
            raise ClusterError(f"--cluster {address}: cannot connect ({_first_line(error)})") from None
        try:
            yield client
        finally:
            client.close()
        return
    check_worker_count(workers)
    with _workers_ignore_ctrl_c():
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


@contextmanager
def _workers_ignore_ctrl_c():
    """Worker processes started inside ignore SIGINT (they inherit it): Ctrl-C in the terminal reaches the whole
    process group, and the replay, not each worker with its own traceback, stops them (closing the cluster)."""
    import signal
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def check_worker_count(workers):
    """ValueError (one line) unless ``workers`` is a positive integer (``--workers N``)."""
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"--workers must be a positive integer, got {workers!r}")


def _worker_version():
    from livedic.acquire.recording.chunked_writer import software_version
    return software_version()


def check_workers(client, timeout_s=None):
    """The cluster's workers can run the replay: livedic importable on each (one line otherwise); returns
    notes (a worker with another livedic version than this process: its numbers may differ by rounding)."""
    from livedic.acquire.recording.chunked_writer import software_version
    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    try:
        client.wait_for_workers(1, timeout=timeout_s)
        versions = client.run(_worker_version)
    except (ImportError, AttributeError) as error:
        raise ClusterError(f"the Dask workers cannot run livedic ({type(error).__name__}: {error}): install it "
                           f"(the same version) where the workers run") from None
    except TimeoutError:
        raise ClusterError(f"the Dask scheduler has no worker (none joined within {timeout_s} s): start some "
                           f"with `dask worker ADDRESS`") from None
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
    """What every worker needs once per replay (besides the key-frame trackers): output rows and numba threads."""
    token: str
    threads: int = 1
    point_ids: np.ndarray | None = None   # with ``strain``: the frame's output rows are made on the worker
    strain: Any = None                    # the session's stream.stages.strain.StrainStage (its compute)
    csv_text: bool = False                # ... and sent as CSV lines (else as columns)


@dataclass(frozen=True)
class Segment:
    """Frames measured against one state of the key-frame tracker: from ``start + 1`` on.

    ``start`` is the position of the frame that built the tracker's inner tracker (-1: the new tracker,
    before the reference frame; else a key frame or a fracture); ``key`` that of the current key frame
    (-1: the first frame). Its tracker, as it was right after frame ``start``, is the task ``future``.
    """
    token: str
    start: int
    key: int
    future: object = None


@dataclass
class FrameMeasured:
    """A worker's answer for one frame (``position``: its place in the replay's frame order)."""
    position: int
    key: tuple
    measurement: Measurement
    refound: np.ndarray
    refind_attempts: int
    trackable: np.ndarray
    seconds: float
    update: object = None                 # dic.tracking.key_frames.ReferenceUpdate: the reference moved to this frame
    fracture: object = None               # dic.tensile.fracture.Fracture detected in this frame
    tracker: object = None                # the KeyFrameTracker after this frame, when this frame rebuilt it
    rows: object = None                   # the frame's output rows (stream.replay.rows.FrameRows)
    rows_seconds: float = 0.0             # the time the worker spent on them (strain and formatting)


_TRACKERS: dict = {}    # per worker thread: (segment token, thread) -> its KeyFrameTracker (a working copy)
_READERS: dict = {}     # per worker process: recording path -> acquire.recording.source.FrameReader


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
    from livedic.acquire.recording.source import FrameReader
    reader = _READERS.get(frame.path)
    if reader is None:
        _READERS.clear()
        reader = _READERS[frame.path] = FrameReader(frame.path)
    return reader.image(frame.index, frame.timestamp_ns)


def _the_data(value):
    return value


def _tracker_for(segment_token, tracker):
    """This worker thread's copy of a segment's tracker (the task's own object stays as it is: tasks share it),
    made once per segment and thread; returns (cache key, copy)."""
    cache_key = (segment_token, threading.get_ident())
    working = _TRACKERS.get(cache_key)
    if working is None:
        for old in [k for k in _TRACKERS if k[1] == cache_key[1]]:
            del _TRACKERS[old]              # this thread's earlier segments are done
        working = _TRACKERS[cache_key] = copy.deepcopy(tracker)
    return cache_key, working


def measure_frame(job, segment_token, tracker, segment_start, key_start, position, key, image, previous,
                  last_good):
    """Measure one frame on a worker: the segment's ``KeyFrameTracker`` resumed from the seed, then ``track``.

    Parameters
    ----------
    job : ReplayJob
    segment_token : str
    tracker : dic.tracking.key_frames.KeyFrameTracker
        As it was right after the frame at ``segment_start`` (``Segment``).
    segment_start, key_start : int
        Positions of that frame and of the current key frame (-1: none).
    position : int
        The frame's place in the replay's order (0: the reference).
    key : (int, int)
        Its (frame index, timestamp ns).
    image : ndarray (H, W) or FrameAt
        As recorded (uint8 or uint16), or where the worker reads it (``--shared-path``).
    previous, last_good
        ``dic.tracking.key_frames.KeyFrameTracker.resume``'s seed: the recorded result before the frame, the last ok ones
        since ``segment_start``.
    """
    import numba
    if numba.get_num_threads() != job.threads:
        numba.set_num_threads(job.threads)
    started = time.perf_counter()
    image = _image_of(image)
    cache_key, working = _tracker_for(segment_token, tracker)
    working.resume(previous, last_good=last_good, frames_tracked=position,
                      frames_since_key=position - key_start - 1, frames_since_rebuild=position - segment_start - 1)
    state = working.state
    measurement = working.track(image)
    seconds = time.perf_counter() - started
    answer = FrameMeasured(position=position, key=key, measurement=measurement,
                           refound=working.last_refound.copy(), refind_attempts=working.last_refind_attempts,
                           trackable=working.trackable.copy(), seconds=seconds, update=working.last_update,
                           fracture=working.last_fracture)
    if working.state is not state:     # a move, a fracture or the crack widening rebuilt it
        answer.tracker = _TRACKERS.pop(cache_key)          # its state moved on: the next segment's tracker
    if job.strain is not None and not working.fractures:  # after a fracture the client's strain stage splits
        strain, _ = job.strain.compute(measurement.u, measurement.v, measurement.ok)
        rows = frame_rows(key[0], key[1], job.point_ids, measurement, strain, job.strain)
        answer.rows = rows.as_text() if job.csv_text else rows
    answer.rows_seconds = time.perf_counter() - started - seconds
    return answer


# ----------------------------------------------------------------------------- seeds

_SEED_FIELDS = ("u", "v", "zncc", "ok", "ux", "uy", "vx", "vy")


def _slim(measurement, take=None):
    """The fields a resumed tracker reads (float64/bool), for the points ``take`` (None: all)."""
    def pick(name, dtype):
        values = getattr(measurement, name)
        if values is None:
            return None
        values = np.asarray(values, dtype=dtype)
        return np.ascontiguousarray(values if take is None else values[take])
    empty = np.zeros(0)
    return Measurement(x=empty, y=empty, u=pick("u", np.float64), v=pick("v", np.float64),
                       zncc=pick("zncc", np.float64), ok=pick("ok", bool), status=np.zeros(0, dtype=np.int8),
                       **{name: pick(name, np.float64) for name in ("ux", "uy", "vx", "vy")})


def nearest_recorded(x, y, recorded_x, recorded_y):
    """For each point (x, y), the index of the nearest recorded point (chunked: no N x M matrix at once)."""
    out = np.empty(len(x), dtype=np.int64)
    rx, ry = np.asarray(recorded_x, dtype=np.float64), np.asarray(recorded_y, dtype=np.float64)
    for start in range(0, len(x), 256):
        d2 = (x[start:start + 256, None] - rx[None, :]) ** 2 + (y[start:start + 256, None] - ry[None, :]) ** 2
        out[start:start + 256] = np.argmin(d2, axis=1)
    return out


class RecordedSeeds:
    """Each frame's recorded result on this replay's points (``of(key)``: a slim ``Measurement`` or None)."""

    def __init__(self, recorded, x, y):
        self.recorded = recorded
        self.x, self.y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        self._layouts = {}

    def of(self, key):
        """The recorded result of frame ``key``: as recorded when on these points, else from the nearest recorded."""
        result = self.recorded.get(key)
        if result is None:
            return None
        m = result.measurement
        if len(m.x) == len(self.x) and np.array_equal(m.x, self.x) and np.array_equal(m.y, self.y):
            return _slim(m)
        layout = (len(m.x), np.asarray(m.x).tobytes(), np.asarray(m.y).tobytes())
        take = self._layouts.get(layout)
        if take is None:
            take = self._layouts[layout] = nearest_recorded(self.x, self.y, m.x, m.y)
        return _slim(m, take)


class SeedRun:
    """The seeds of consecutive frames of one segment: (the last recorded result before the frame, the last ok
    one of every point since the segment's start). ``next(recorded)`` gives the frame's seed and then takes its
    recorded result (None: none) into account."""

    def __init__(self, previous):
        self.previous = previous
        self.last_good = None

    def next(self, recorded):
        last_good = self.last_good
        if last_good is not None and not np.any(last_good["ever"] & ~self.previous.ok):
            last_good = None        # every point ever ok is ok in the previous frame: resume's default is the same
        seed = (self.previous, last_good)
        if recorded is not None:
            self.previous = recorded
            self.last_good = last_good_after(self.last_good, recorded)
        return seed


def recorded_rebuilds(recorded):
    """Keys (index, timestamp) of the frames whose recorded results show the live tracker rebuilt its key-frame
    state there: the reference moved to it (the next results name it as their reference) or more points were
    separated by a fracture. ``recorded``: key -> ``RecordedResults``, in recorded order."""
    keys = set()
    previous_key = previous_reference = None
    separated = 0
    for key, result in recorded.items():
        reference = int(result.reference_frame_index)
        if previous_key is not None and reference != previous_reference and reference == previous_key[0]:
            keys.add(previous_key)
        status = result.status
        now = 0 if status is None else int(np.count_nonzero(np.asarray(status) == SEPARATED))
        if now > separated:
            keys.add(key)
        separated = max(separated, now)
        previous_key, previous_reference = key, reference
    return keys


# ----------------------------------------------------------------------------- the client side

@dataclass
class _Pending:
    key: tuple
    image: object                 # what the task is given: the image, or where to read it
    recorded: object              # the frame's recorded result (seed of the next ones), or None
    future: object = None


class OrderedResults:
    """Submit the frames of ``frames`` to ``client`` (at most ``in_flight`` ahead) and hand their results back
    in order, each exactly once (``take(position, key)`` checks both).

    The frames are measured against the current ``Segment``'s tracker; a frame whose result moved the reference
    or detected a fracture starts a new segment: the frames submitted after it are submitted again against the
    tracker as it left that frame (the results already computed for them were measured against the old one).
    """

    def __init__(self, client, job, tracker, frames, seeds, in_flight, shared_path=None, rebuilds=()):
        self.client = client
        self.token = job.token
        # Tasks, not Client.scatter: the scheduler keeps what they were made from, so a worker that dies holding
        # the only copy costs a recomputation, not the replay (scattered data would be lost with it).
        self.job_future = client.submit(_the_data, job, key=f"livedic-replay-job-{job.token}", pure=False)
        self.segment = self._segment(tracker, start=-1, key=-1)
        self.segments = 1
        self.frames = iter(frames)
        self.seeds = seeds
        self.run = SeedRun(None)
        self.taken_previous = None   # the last recorded result up to the last frame taken
        self.in_flight = max(1, int(in_flight))
        self.pending = {}            # position -> _Pending
        self.submitted = 0
        self.taken = 0
        self.exhausted = False
        self.shared_path = shared_path
        self.image_bytes = 0         # what the frames weighed on the wire (their images; 0 when workers read them)
        self.seed_bytes = 0
        self.resubmitted = 0         # frames submitted again after a reference move or a fracture
        # Where the recording says the reference moved or a fracture stopped points: nothing is submitted past
        # such a frame until its result is in (what would be measured ahead against the old state is wasted).
        self.rebuilds = set(rebuilds)
        self.hold = None
        self.wait_seconds = 0.0      # the client blocked on the next result (the rest of its time is its own work)

    def _segment(self, tracker, *, start, key):
        token = f"{self.token}-{start}"
        future = self.client.submit(_the_data, tracker, key=f"livedic-replay-tracker-{token}", pure=False)
        return Segment(token=token, start=start, key=key, future=future)

    def _submit(self, position, pending):
        previous, last_good = self.run.next(pending.recorded)
        self.seed_bytes += _nbytes(previous) + _nbytes(last_good)
        segment = self.segment
        pending.future = self.client.submit(
            measure_frame, self.job_future, segment.token, segment.future, segment.start, segment.key, position,
            pending.key, pending.image, previous, last_good,
            key=f"livedic-replay-frame-{segment.token}-{position}", retries=TASK_RETRIES, pure=False)

    def _submit_more(self):
        while not self.exhausted and self.submitted < self.taken + self.in_flight and self.hold is None:
            frame = next(self.frames, None)
            if frame is None:
                self.exhausted = True
                return
            key = (int(frame.index), int(frame.timestamp_ns))
            if self.shared_path is None:
                image = np.ascontiguousarray(frame.image)
                self.image_bytes += image.nbytes
            else:
                image = FrameAt(self.shared_path, *key)
            pending = self.pending[self.submitted] = _Pending(key=key, image=image, recorded=self.seeds.of(key))
            self._submit(self.submitted, pending)
            if key in self.rebuilds:
                self.hold = self.submitted
            self.submitted += 1

    def _new_segment(self, position, answer):
        """The frame at ``position`` moved the reference or broke: the frames after it against its tracker."""
        key = position if answer.update is not None else self.segment.key
        self.segment = self._segment(answer.tracker, start=position, key=key)
        self.segments += 1
        self.run = SeedRun(self.taken_previous)
        for later in sorted(self.pending):
            pending = self.pending[later]
            pending.future.cancel()
            self._submit(later, pending)
            self.resubmitted += 1

    def take(self, position, key):
        """The result of the frame at ``position`` (0 first), which must be the frame ``key``."""
        if position != self.taken:
            raise RuntimeError(f"parallel replay: frame at position {position} asked for, {self.taken} expected")
        self._submit_more()
        pending = self.pending.pop(position, None)
        if pending is None:
            raise RuntimeError(f"parallel replay: no task for the frame at position {position} (frame {key[0]}): "
                               f"the session and the submitted frames disagree")
        started = time.perf_counter()
        try:
            answer = pending.future.result()
        except ValueError as error:             # RecordingError: a worker could not read the shared recording
            if self.shared_path is None:
                raise
            raise ValueError(f"a worker could not read frame {key[0]} from {self.shared_path} ({error}); "
                             f"--shared-path must name the recording as every worker sees it") from None
        self.wait_seconds += time.perf_counter() - started
        pending.future.release()
        if answer.position != position or tuple(answer.key) != tuple(key) or tuple(pending.key) != tuple(key):
            raise RuntimeError(f"parallel replay: the result for position {position} is frame {answer.key[0]} "
                               f"at position {answer.position}, not frame {key[0]}")
        self.taken += 1
        if self.hold == position:
            self.hold = None
        if pending.recorded is not None:
            self.taken_previous = pending.recorded
        if answer.tracker is not None:
            self._new_segment(position, answer)
            answer.tracker = None
        self._submit_more()
        return answer

    def check_complete(self):
        """RuntimeError unless every submitted frame's result was taken once and no frame is left unsent."""
        if self.pending or not self.exhausted and next(self.frames, None) is not None:
            raise RuntimeError(f"parallel replay: {len(self.pending)} frame result(s) submitted but not written "
                               f"(written {self.taken} of {self.submitted})")

    def cancel(self):
        for pending in self.pending.values():
            if pending.future is not None:
                pending.future.cancel()
        self.pending.clear()


def _nbytes(value):
    if value is None:
        return 0
    arrays = value.values() if isinstance(value, dict) else (getattr(value, name) for name in _SEED_FIELDS)
    return sum(a.nbytes for a in arrays if a is not None)


class ServedTracker:
    """What the replay session tracks with: each frame's result measured on the cluster, in order.

    It stands in the session for the ``KeyFrameTracker`` the session built on the reference (the workers'
    copies of it did the tracking) and says what they said: reference updates, fractures, re-found points.
    """

    def __init__(self, tracker, results, keys, *, keep_rows=False):
        self.tracker = tracker
        self.results = results
        self.keys = keys
        # frame key -> (header, lines) formatted by its worker, until the session's output thread (which runs
        # behind the tracking thread) takes them (``ParallelSession.rows_of``)
        self.rows = {} if keep_rows else None
        self.frames_tracked = 0
        self.trackable = tracker.trackable
        self.last_refound = np.zeros(tracker.n_points, dtype=bool)
        self.last_refind_attempts = 0
        self.last_seed_searches = 0
        self.last_update = None
        self.last_fracture = None
        self.compute_seconds = 0.0
        self.rows_seconds = 0.0

    @property
    def n_points(self):
        return self.tracker.n_points

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
        self.frames_tracked += 1
        self.compute_seconds += answer.seconds
        self.rows_seconds += answer.rows_seconds
        self.last_refound = answer.refound
        self.last_refind_attempts = answer.refind_attempts
        self.trackable = answer.trackable
        self.last_update = answer.update
        self.last_fracture = answer.fracture
        if self.rows is not None:
            self.rows[tuple(answer.key)] = answer.rows
        return answer.measurement


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
    shared_path: str | None = None        # where the workers read the frames (None: sent from the client)
    wait_seconds: float = 0.0             # the replaying process waiting for results (the rest: its own work)
    segments: int = 1                     # trackers measured against: 1 + reference moves + fractures
    resubmitted: int = 0                  # frames measured again against a new segment's tracker


class ParallelSession(Session):
    """The replay's ``Session`` with its frames measured on a Dask cluster (``ServedTracker``); same sinks.

    It gives the session its tracker factory (``serve``): the tracker a sequential replay would use, built on the
    reference, stands for the workers' copies of it.
    """

    def __init__(self, config, *, client, frames_again, recorded, in_flight=None, shared_path=None, point_ids=None,
                 rows=None, stats=None, **kwargs):
        self._keys = deque()
        source = kwargs.pop("source")
        super().__init__(config, source=KeyedFrames(source, self._keys), tracker_factory=self.serve, **kwargs)
        self._client = client
        self._frames_again = frames_again
        self._recorded = recorded
        self._in_flight = in_flight
        self._shared_path = shared_path
        self._point_ids = point_ids            # a list the replay fills with the point ids after ``prepare``
        self._rows = rows                      # None, "csv" (lines made on the workers) or "columns"
        self.parallel = stats if stats is not None else ParallelStats()
        self.served = None
        self.results = None

    def serve(self, reference_image: np.ndarray, points: np.ndarray) -> ServedTracker:
        """The ``ServedTracker`` on the reference: the results of the cluster's copies of the tracker a sequential
        replay would build there (``config.tracking.tracker``), in order."""
        tracker = self.config.tracking.tracker(reference_image, points)
        threads = cluster_threads(self._client)
        rows = self._rows is not None and self.strain is not None
        job = ReplayJob(token=uuid.uuid4().hex, threads=1, point_ids=np.asarray(self._point_ids[0]) if rows else None,
                        strain=self.strain if rows else None, csv_text=self._rows == "csv")
        seeds = RecordedSeeds(self._recorded, tracker.x, tracker.y)
        in_flight = self._in_flight or IN_FLIGHT_PER_WORKER * threads
        self.results = OrderedResults(self._client, job, copy.deepcopy(tracker), self._frames_again, seeds, in_flight,
                                      self._shared_path, rebuilds=recorded_rebuilds(self._recorded))
        self.served = ServedTracker(tracker, self.results, self._keys, keep_rows=rows)
        self.parallel.workers = threads
        return self.served

    def rows_of(self, frame):
        """The output rows (``FrameRows``) of ``frame`` as its worker made them, taken once; None when it did not
        (no rows asked for; after a fracture: the strain windows split by the crack are the session's)."""
        key = (int(frame.index), int(frame.timestamp_ns))
        rows = self.served.rows if self.served is not None else None
        if rows is None:
            return None
        if key not in rows:
            raise RuntimeError(f"parallel replay: no result for frame {frame.index}")
        return rows.pop(key)

    def finish_parallel(self):
        """After ``run``: every frame taken once (RuntimeError otherwise); fills ``parallel``."""
        if self.results is None:
            return self.parallel
        self.results.check_complete()
        stats = self.parallel
        results = self.results
        stats.frames = results.taken
        stats.compute_seconds = self.served.compute_seconds
        stats.rows_seconds = self.served.rows_seconds
        stats.image_bytes = results.image_bytes
        stats.seed_bytes = results.seed_bytes
        stats.shared_path = results.shared_path
        stats.wait_seconds = results.wait_seconds
        stats.segments = results.segments
        stats.resubmitted = results.resubmitted
        return stats

    def close(self):
        if self.results is not None:
            self.results.cancel()
        return super().close()
