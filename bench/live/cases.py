"""One case of ``livedic bench live``: a ``livedic run`` session on the simulator, as a row of summary numbers.

Also the benchmark's configuration (point counts, methods, targets) and the strain-out latency of a case.
"""

import json
import os
import time

from livedic.dic import DEFAULT_SUBSET
from livedic.dic.search import DEFAULT_SEARCH

from livedic.bench.live.receiver import StrainOutReceiver

POINT_COUNTS = (400, 1000, 2500)
METHODS = ("improved-surface-fit", "icgn")
TARGET_POINTS = 1000
TARGET_METHOD = "icgn"
TARGET_FPS = 50.0
TARGET_P99_MS = 25.0
TARGET_STRAIN_MS = 2.0
TARGET_STRAIN_OUT_P99_MS = 5.0
GAUGE_LENGTH_PX = 400.0       # the main job's --gauge-length (setup.sh, docs/guide/index.md)


class ResultTimes:
    """A session sink keeping each frame's result time (``FrameResult.done_ns``), where strain-out latency starts."""
    name = "result times"
    required = False

    def __init__(self):
        self.done_ns = {}

    def __call__(self, result, stats):
        self.done_ns[result.frame.index] = result.done_ns


def _percentiles_ms(values_ns):
    """(p50, p99) in ms of ``values_ns``, (None, None) when empty."""
    if not values_ns:
        return None, None
    import numpy as np
    values = np.asarray(values_ns, dtype=np.float64) / 1e6
    return float(np.percentile(values, 50)), float(np.percentile(values, 99))


def strain_out_numbers(publish, done_ns, received):
    """The strain-out latency of one session: the ``publish`` summary entry, result times, the receiver's datagrams.

    Returns
    -------
    dict
        ``sent``, ``failed``, ``received``, ``frames``; ``sent_p50_ms``/``sent_p99_ms`` (result -> send
        returned), ``upstream_p50_ms``/``upstream_p99_ms`` (result -> the publisher's start), ``stage_p50_ms``/
        ``stage_p99_ms`` (inside the publisher), ``arrival_p50_ms``/``arrival_p99_ms``
        (result -> in the receiving socket; None without kernel timestamps), ``read_p50_ms``/``read_p99_ms``
        (result -> the receiving thread's read).
    """
    arrivals = [arrival - done_ns[frame] for frame, arrival, _ in received if frame in done_ns and arrival is not None]
    reads = [read - done_ns[frame] for frame, _, read in received if frame in done_ns]
    arrival_p50, arrival_p99 = _percentiles_ms(arrivals)
    read_p50, read_p99 = _percentiles_ms(reads)
    return {"sent": publish.get("sent"), "failed": publish.get("failed"), "received": len(received),
            "frames": len(done_ns), "sent_p50_ms": publish.get("latency_p50_ms"),
            "sent_p99_ms": publish.get("latency_p99_ms"), "upstream_p50_ms": publish.get("upstream_p50_ms"),
            "upstream_p99_ms": publish.get("upstream_p99_ms"), "stage_p50_ms": publish.get("stage_p50_ms"),
            "stage_p99_ms": publish.get("stage_p99_ms"), "arrival_p50_ms": arrival_p50,
            "arrival_p99_ms": arrival_p99, "read_p50_ms": read_p50, "read_p99_ms": read_p99}


def gauge_length_for(size):
    """The axial extensometer's length on the ``size`` x ``size`` simulated test: 400 px, or 0.75 x the ROI height."""
    from livedic.acquire.simulator.sources import SyntheticTensileSource
    roi_height = SyntheticTensileSource(f"synthetic:tensile?size={size}x{size}&frames=2").suggested_roi[3]
    return min(GAUGE_LENGTH_PX, float(round(0.75 * roi_height)))


def run_one_session(make_config, said, *, sinks=()):
    """One session from ``make_config()`` to its end, what it said into ``said``; (the ``Session`` or None, the
    error text or None): a failed case must not hide the others."""
    from livedic.stream.session.session import Session
    session = None
    try:
        with Session(make_config(), sinks=list(sinks), say=lambda message: said.append(f"livedic: {message}")) \
                as session:
            session.execute()
    except Exception as error:  # noqa: BLE001 - one failed case must not hide the others
        return session, f"{type(error).__name__}: {error}"
    if session.source_error is not None:
        return session, f"{type(session.source_error).__name__}: {session.source_error}"
    return session, None


def run_case(*, size, frames, fps, n_points, subpixel, record=True, paced=True, threads=1, workdir,
             search=DEFAULT_SEARCH, subset=DEFAULT_SUBSET, echo=None, gauge_length=None):
    """One ``livedic run`` session; returns a row dict (summary numbers, render time, error text).

    ``echo(text)`` receives what the session said and its summary, when given. ``gauge_length``
    (px): the axial/transverse extensometer pair (``--gauge-length``); None: ``gauge_length_for(size)``.
    """
    from livedic.stream.session.config import PointsConfig, SessionConfig, TrackingConfig
    from livedic.stream.output.files import json_text
    from livedic.stream.stages.strain import StrainConfig

    tag = f"{n_points}-{search}-{subpixel}-{'rec' if record else 'norec'}-{'paced' if paced else 'unpaced'}"
    record_path = os.path.join(workdir, f"{tag}.mcap")
    uri = f"synthetic:tensile?size={size}x{size}&fps={fps:g}&frames={frames}" + ("" if paced else "&pace=0")
    gauge_length = gauge_length_for(size) if gauge_length is None else gauge_length
    row = dict(points_wanted=n_points, subpixel=subpixel, search=search, record=record, paced=paced,
               fps_offered=fps if paced else None, size=size, frames_offered=frames, error=None, render_s=None,
               gauge_length=gauge_length, summary={}, strain_out=None)
    said = []
    receiver = StrainOutReceiver()
    times = ResultTimes()
    started = time.perf_counter()
    try:
        session, row["error"] = run_one_session(
            lambda: SessionConfig(source=uri, points=PointsConfig(n_points=n_points),
                                  tracking=TrackingConfig(subset=subset, search=search, subpixel=subpixel),
                                  record=record_path if record else None, threads=threads,
                                  command="livedic bench live", strain=StrainConfig(gauge_length=gauge_length),
                                  publish=(receiver.uri,)), said, sinks=[times])
    finally:
        received = receiver.stop()
    row["wall_s"] = time.perf_counter() - started
    if session is not None:
        row["render_s"] = session.render_seconds
        if session.summary() is not None:
            row["summary"] = json.loads(json_text(session.summary()))     # None where a number is missing
            publish = (row["summary"].get("publish") or [{}])[0]
            row["strain_out"] = strain_out_numbers(publish, times.done_ns, received)
            row["strain_out"]["kernel_stamps"] = receiver.kernel_stamps
    if echo is not None:
        echo("\n".join(said + ([session.summary_text()] if session is not None and session.summary_text() else [])))
    if os.path.exists(record_path):
        os.remove(record_path)
    return row
