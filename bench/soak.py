"""``livedic bench soak``: a long session through the full pipeline; memory and frame accounting.

Setup (issue 4): 20,000 frames of the simulated tensile test through the
session ``livedic run`` runs (``stream.session.session.Session``, its config built with
run's defaults): the acquisition thread, the bounded queue (4 frames, drop the
oldest, as for a camera), the tracker (1,000 points, subset 21, improved-wso +
IC-GN by default, P0 placed as run places it) and the recorder (every frame and
every result into an MCAP file in a temporary folder, deleted afterwards unless
``keep``). No viewer. The soak adds one sink, its monitor (progress, RSS), and
counts the frames where the source yields them.

The source is ``synthetic:tensile?...&loop=K``: only K frames (default 200)
are rendered and the 20,000 delivered frames cycle through them forward and
back (a cyclic load-unload test, frame indices and timestamps increasing), so
memory does not grow with the length of the run and every frame still has an
exact truth. Default 512x512 Mono8 at 50 fps paced: 20,000 frames take 400 s
and write 5.2 GB of frames, ~6.6 GB with the results (1 MP would be 21 GB of
frames; ``size`` changes it).

Memory: the resident set (VmRSS in /proc/self/status) is sampled before the
pipeline starts (kernels compiled, frames rendered), after a warm-up of
``warmup_frames`` tracked frames (first-touch allocations of the tracker,
queue and recorder), every ``progress_every`` frames, and at the end. Growth
is end against after-warm-up; a least-squares slope over the samples shows a
trend that a single end point could hide.

Where the memory goes: the mcap writer keeps one index entry per chunk until the
file is closed (the report gives the chunks written and per frame), and the
session statistics keep three packed 64-bit integers per tracked frame (the
report gives their size, ~0.5 MB for 20,000 frames).

Accounting: frames produced by the source (counted where it yields them),
frames recorded (read back from the MCAP file with ``acquire.recording.reader``),
frames tracked and frames dropped by the queue. Every produced frame is
accounted for when recorded == produced and tracked + dropped == produced.
"""

import math
import os
import shutil
import sys
import tempfile
import threading
import time
from dataclasses import dataclass

from livedic.dic.search import DEFAULT_SEARCH

DEFAULT_FRAMES = 20_000
DEFAULT_SIZE = 512
DEFAULT_LOOP = 200
RSS_GROWTH_LIMIT = 0.05


def rss_mb(field="VmRSS"):
    """The process's resident set (or another /proc/self/status field) in MB; nan where unavailable."""
    try:
        with open("/proc/self/status") as handle:
            for line in handle:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def _load():
    try:
        return "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "load average n/a"


def _deep_size(obj, seen=None):
    """Rough bytes held by ``obj`` and what it references (dicts, lists, dataclass fields)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return 0
    seen.add(id(obj))
    size = sys.getsizeof(obj)
    if isinstance(obj, dict):
        size += sum(_deep_size(k, seen) + _deep_size(v, seen) for k, v in obj.items())
    elif isinstance(obj, (list, tuple, set)):
        size += sum(_deep_size(v, seen) for v in obj)
    elif hasattr(obj, "__dict__"):
        size += _deep_size(vars(obj), seen)
    return size


def mcap_index_memory(recorder):
    """(chunks, estimated MB) the mcap writer keeps in memory to write the file's summary, or None.

    The writer holds one ``ChunkIndex`` per chunk written until ``finish``; the
    recorder keeps chunks few (images by size or age, results and events together
    every ``flush_interval_s``: ~0.15 chunks per frame at 512x512 and 50 fps). Best
    effort (``Recorder.chunk_indexes``): None where the library does not say.
    """
    try:
        indices = recorder.chunk_indexes()
        sample = indices[-200:]
        seen = set()          # objects shared between indexes (small ints, strings) counted once
        per_chunk = sum(_deep_size(index, seen) for index in sample) / max(len(sample), 1)
        return len(indices), len(indices) * per_chunk / 1e6
    except Exception:  # noqa: BLE001 - a diagnostic, never a failure
        return None


class CountingSource:
    """Wraps a frame source and counts the frames it yields (what the source produced)."""

    def __init__(self, source):
        self.source = source
        self.produced = 0

    def __iter__(self):
        for frame in self.source:
            self.produced += 1
            yield frame

    def close(self):
        self.source.close()

    def __getattr__(self, name):
        return getattr(self.source, name)


def run_soak_benchmark(*, frames=DEFAULT_FRAMES, size=DEFAULT_SIZE, fps=50.0, n_points=1000, subpixel="icgn",
                       search=DEFAULT_SEARCH, loop=DEFAULT_LOOP, queue=4, threads=1, keep=False, directory=None,
                       progress_every=1000, warmup_frames=200, max_wall_s=None, log=print):
    """Run the soak, print progress and the verdicts; returns a result dict.

    Parameters
    ----------
    frames : int
        Frames the source produces (default 20,000).
    size : int
        Square image side in pixels (default 512: 20,000 frames record 5.2 GB).
    fps : float
        Paced rate of the simulated camera.
    loop : int
        Frames rendered and cycled forward and back (``loop=`` option of the simulator).
    keep : bool
        Keep the recording (its path is printed); otherwise it is deleted.
    directory : str, optional
        Where the recording goes (default: a new temporary folder).
    max_wall_s : float, optional
        Safety stop: end acquisition after this long (default 3 x the paced duration + 120 s).
    log : callable
        Receives each output line.

    Returns
    -------
    dict
        produced, recorded, recorded_written, results_recorded, tracked, dropped, rss_* (MB),
        rss_growth, rss_samples [(frames, MB)], chunks (written), chunks_per_frame (per produced frame),
        mcap_index ((chunk indexes, MB) or None), stats_mb, passed_rss, passed_accounting, lines,
        recording (path or None).
    """
    if frames < 2:
        raise ValueError(f"--frames must be >= 2, got {frames}")
    printed = []

    def say(text=""):
        printed.append(text)
        log(text)

    plan = _plan(frames=frames, size=size, fps=fps, n_points=n_points, subpixel=subpixel, search=search, loop=loop,
                 queue=queue, threads=threads, directory=directory, warmup_frames=warmup_frames,
                 max_wall_s=max_wall_s)
    _say_plan(plan, keep, say)
    result = {}
    try:
        run = _run_session(plan, progress_every, say)
        _say_warnings(run, plan, say)
        result = _account(run, plan, say)
        result["recording"] = plan.record_path if keep else None
    finally:
        if keep:
            say(f"  recording kept: {plan.record_path}")
        elif directory is None:
            shutil.rmtree(plan.workdir, ignore_errors=True)
        elif os.path.exists(plan.record_path):
            os.remove(plan.record_path)
    result["lines"] = printed
    return result


@dataclass
class _Plan:
    """What the soak runs: the source, where it records, the session's config, the warm-up and the safety stop."""

    frames: int
    size: int
    fps: float
    loop: int
    warmup_frames: int
    uri: str
    workdir: str
    record_path: str
    config: object
    max_wall_s: float


def _plan(*, frames, size, fps, n_points, subpixel, search, loop, queue, threads, directory, warmup_frames,
          max_wall_s):
    from livedic.stream.session.config import PointsConfig, SessionConfig, TrackingConfig

    loop = max(2, min(loop, frames))
    warmup_frames = max(1, min(warmup_frames, frames // 10))     # short runs: a tenth of the frames
    uri = f"synthetic:tensile?size={size}x{size}&fps={fps:g}&frames={frames}&loop={loop}"
    workdir = directory or tempfile.mkdtemp(prefix="livedic-bench-soak-")
    os.makedirs(workdir, exist_ok=True)
    record_path = os.path.join(workdir, f"soak-{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}.mcap")
    # livedic run's session with these options: --n-points, --search, --subpixel, --queue, --drop oldest,
    # --threads, --record, --viewer none, --progress off (the rest at run's defaults).
    config = SessionConfig(source=uri, points=PointsConfig(n_points=n_points),
                           tracking=TrackingConfig(search=search, subpixel=subpixel), record=record_path, queue=queue,
                           drop="oldest", threads=threads, command="livedic bench soak")
    return _Plan(frames=frames, size=size, fps=fps, loop=loop, warmup_frames=warmup_frames, uri=uri, workdir=workdir,
                 record_path=record_path, config=config, max_wall_s=max_wall_s or 3.0 * frames / fps + 120.0)


def _say_plan(plan, keep, say):
    config, size, frames = plan.config, plan.size, plan.frames
    tracking = config.tracking
    say(f"livedic bench soak: {frames} frames, {plan.uri}")
    say(f"  {size}x{size} Mono8 ({size * size * frames / 1e9:.1f} GB of frames to record), {plan.loop} rendered frames "
        f"cycled forward and back, paced at {plan.fps:g} fps ({frames / plan.fps:.0f} s); "
        f"{config.points.n_points} points wanted, subset {tracking.subset}, {tracking.search} + {tracking.subpixel}; "
        f"queue {config.queue} drop-oldest; recording into {plan.record_path}"
        f"{' (kept)' if keep else ' (deleted afterwards)'}; viewer none; {config.threads} numba thread(s)")
    say(f"  machine: {os.cpu_count()} CPU cores; {_load()} at start")


class _Monitor:
    """The soak's sink: RSS after the warm-up and every ``progress_every`` produced frames, and a progress line."""

    def __init__(self, plan, progress_every, started, say):
        self.plan, self.progress_every, self.started, self.say = plan, progress_every, started, say
        self.samples = []          # (frames tracked, RSS MB) after the warm-up
        self.block = {"start": time.perf_counter(), "frames": 0, "err_sq": 0.0, "err_n": 0}
        self.marks = {}
        self.session = None
        self.counting = None

    def __call__(self, res, stats):
        block, marks = self.block, self.marks
        if math.isfinite(res.error_rms_px) and not res.is_reference:
            block["err_sq"] += res.error_rms_px ** 2
            block["err_n"] += 1
        if stats.frames == self.plan.warmup_frames:
            marks["rss_warm"] = rss_mb()
            marks["warm_frames"] = stats.frames
            self.samples.append((stats.frames, marks["rss_warm"]))
        produced = self.counting.produced
        if stats.frames == 1:
            self.say(f"  reference frame {res.frame.index}: {len(self.session.points)} points, set-up "
                     f"{res.processing_ns / 1e6:.0f} ms, RSS {rss_mb():.1f} MB")
            block.update(start=time.perf_counter(), frames=1)
            return
        if produced // self.progress_every > block.get("shown", 0):
            block["shown"] = produced // self.progress_every
            self._progress(produced, stats)

    def _progress(self, produced, stats):
        import numpy as np

        block, session = self.block, self.session
        now = time.perf_counter()
        rss = rss_mb()
        if stats.frames > self.plan.warmup_frames:
            self.samples.append((stats.frames, rss))
        span = now - block["start"]
        tracked = stats.frames - block["frames"]
        lat = stats.latencies_ns[-max(tracked, 1):]
        p99 = np.percentile(np.asarray(lat), 99) / 1e6 if lat else float("nan")
        err = math.sqrt(block["err_sq"] / block["err_n"]) if block["err_n"] else float("nan")
        self.say(f"  {produced:>6d}/{self.plan.frames} produced  {stats.frames:>6d} tracked  "
                 f"{session.queue.dropped:>5d} dropped  {session.recorder.frames_written:>6d} recorded  "
                 f"{(tracked / span if span > 0 else float('nan')):5.1f} fps  latency p99 {p99:6.1f} ms  "
                 f"error {err:.4f} px  RSS {rss:7.1f} MB  {time.perf_counter() - self.started:5.0f} s")
        block.update(start=now, frames=stats.frames, err_sq=0.0, err_n=0)


@dataclass
class _Run:
    """What the session left: its statistics, the recorder, and memory at each point of the run."""

    session: object
    monitor: _Monitor
    stats: object
    recorder: object
    rss_before: float
    rss_end: float
    rss_closed: float
    index_memory: object
    stats_mb: float
    chunks: int
    wall: float


def _run_session(plan, progress_every, say):
    """The session to its end (or the safety timer), the recording closed; memory sampled around it."""
    from livedic.acquire.sources import open_source
    from livedic.stream.session.session import Session
    from livedic.stream.pipeline.sinks import FunctionSink

    started = time.perf_counter()
    monitor = _Monitor(plan, progress_every, started, say)
    monitor.counting = CountingSource(open_source(plan.uri))
    session = Session(plan.config, source=monitor.counting, sinks=[FunctionSink(monitor, "soak monitor")],
                      say=lambda message: say(f"  {message}"))
    monitor.session = session
    with session:
        session.prepare()             # kernels compiled, frames rendered, points placed, recording opened
        rss_before = rss_mb()
        timer = threading.Timer(plan.max_wall_s, session.stop)
        timer.daemon = True
        session.start()
        timer.start()
        try:
            stats = session.run()
        finally:
            timer.cancel()
        recorder = session.recorder
        rss_end = rss_mb()
        monitor.samples.append((stats.frames, rss_end))
        index_memory = mcap_index_memory(recorder)
        stats_mb = sum(sys.getsizeof(values) for values in
                       (stats.latencies_ns, stats.processing_ns, stats.delivery_delays_ns)) / 1e6
        recorder.close()
        chunks = recorder.chunks_written
        rss_closed = rss_mb()
    return _Run(session=session, monitor=monitor, stats=stats, recorder=recorder, rss_before=rss_before,
                rss_end=rss_end, rss_closed=rss_closed, index_memory=index_memory, stats_mb=stats_mb, chunks=chunks,
                wall=time.perf_counter() - started)


def _say_warnings(run, plan, say):
    session = run.session
    for name, error in session.sink_errors:
        say(f"  warning: sink {name} stopped: {type(error).__name__}: {error}")
    if session.source_error is not None:
        say(f"  warning: the source failed: {session.source_error}")
    if session.acquisition.finished_reason == "stopped":
        say(f"  warning: stopped by the safety timer after {plan.max_wall_s:.0f} s")
    if run.recorder.error:
        say(f"  warning: {run.recorder.error}")


def _account(run, plan, say):
    """Read the recording back, say the frame accounting and the memory, judge both; the result dict."""
    import numpy as np

    from livedic.acquire.recording.reader import inspect_recording
    from livedic.acquire.recording.schema import TOPIC_RESULTS

    session, recorder, marks, samples = run.session, run.recorder, run.monitor.marks, run.monitor.samples
    t0 = time.perf_counter()
    info = inspect_recording(plan.record_path)
    readback_s = time.perf_counter() - t0
    recorded = info.frames
    results_recorded = info.message_counts.get(TOPIC_RESULTS, 0)
    produced = run.monitor.counting.produced
    tracked, dropped = run.stats.frames, session.queue.dropped
    rss_warm = marks.get("rss_warm", run.rss_before)
    growth = (run.rss_end - rss_warm) / rss_warm if rss_warm else float("nan")
    after = [(n, mb) for n, mb in samples if n >= marks.get("warm_frames", 0)]
    slope = None
    if len({n for n, _ in after}) >= 3:
        slope = float(np.polyfit([n for n, _ in after], [mb for _, mb in after], 1)[0]) * 10_000
    size_gb = os.path.getsize(plan.record_path) / 1e9

    summary = session.summary()
    say("")
    say(f"soak: {produced} frames in {run.wall:.0f} s ({_load()} at end)")
    say(f"  frames   produced {produced} | recorded {recorded} (read back from the MCAP, {size_gb:.2f} GB, "
        f"{readback_s:.0f} s; recorder counted {recorder.frames_written}) | tracked {tracked} "
        f"(results recorded {results_recorded}) | dropped {dropped}")
    say(f"  rate     {summary['fps']:.1f} fps tracked, latency p50 {summary['latency_p50_ms']:.1f} ms, "
        f"p99 {summary['latency_p99_ms']:.1f} ms, tracking p50 {summary['processing_p50_ms']:.1f} ms, "
        f"{len(session.points)} points, error RMS "
        f"{summary['error_rms_px'] if summary['error_rms_px'] is not None else float('nan'):.4f} px")
    say(f"  RSS      start {rss_warm:.1f} MB (after {marks.get('warm_frames', 0)} frames of warm-up), end "
        f"{run.rss_end:.1f} MB, growth {100 * growth:+.2f} %; before the pipeline started {run.rss_before:.1f} MB, "
        f"after closing the recording {run.rss_closed:.1f} MB, peak {rss_mb('VmHWM'):.1f} MB"
        + (f"; trend {slope:+.2f} MB per 10,000 frames ({len(after)} samples)" if slope is not None else ""))
    index_mb = f"~{run.index_memory[1]:.1f} MB" if run.index_memory is not None else "size unknown"
    say(f"  where    {run.chunks} chunks written ({run.chunks / max(produced, 1):.3f} per produced frame): the mcap "
        f"writer holds an index entry per chunk in memory until the file is closed ({index_mb}, for the "
        f"summary); the session statistics keep 3 packed int64 per tracked frame ({run.stats_mb:.2f} MB)")
    passed_rss = bool(growth < RSS_GROWTH_LIMIT)
    accounted = recorded == produced and tracked + dropped == produced
    say(f"{'PASS' if passed_rss else 'FAIL'}  RSS growth < {100 * RSS_GROWTH_LIMIT:.0f} %: {100 * growth:+.2f} % "
        f"({rss_warm:.1f} -> {run.rss_end:.1f} MB)")
    say(f"{'PASS' if accounted else 'FAIL'}  every produced frame accounted for: recorded {recorded} "
        f"{'==' if recorded == produced else '!='} produced {produced}; tracked {tracked} + dropped {dropped} "
        f"= {tracked + dropped} {'==' if tracked + dropped == produced else '!='} produced {produced}")
    return dict(produced=produced, recorded=recorded, recorded_written=recorder.frames_written,
                results_recorded=results_recorded, tracked=tracked, dropped=dropped, rss_before=run.rss_before,
                rss_start=rss_warm, rss_end=run.rss_end, rss_growth=growth, rss_samples=samples,
                rss_trend_mb_per_10k=slope, mcap_index=run.index_memory, chunks=run.chunks,
                chunks_per_frame=run.chunks / max(produced, 1), stats_mb=run.stats_mb, passed_rss=passed_rss,
                passed_accounting=accounted, wall_s=run.wall, summary=summary)
