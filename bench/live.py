"""``livedic bench live``: the real live pipeline on simulated 1 MP frames, fps and latency.

First the main job as ``./setup.sh`` runs it (``livedic run --gauge-length 400 --load synthetic``,
built from those very words by ``livedic run``'s parser: recording, Rerun ``.rrd``, strain, two
extensometers, force), plus strain out to a UDP socket, on ``synthetic:tensile`` 1024x1024 at 50 fps
and at 100 fps, and unpaced (frames as fast as the pipeline takes them, a blocking queue, the rendered
frames cycled) for the main job's points and for 2,000: frames tracked, drops, latency, the frames
whose camera image the view left out, and per frame the p50/p99 of every stage (the summary's
``stages``: the tracker's own stages from ``Tracker.last_timings``, the tracking thread's stages, the
output thread's sinks, the acquisition thread's recording of the frame), with the tracker's total
against its IC-GN kernel's in the same run. Verdicts (issue 20): every frame tracked, none dropped,
latency p99 <= 25 ms and error RMS <= 0.012 px at 50 and at 100 fps; unpaced >= 200 fps for the main
job's points and >= 100 fps for 2,000; tracker / kernel <= 1.5x.

Then the pipeline by point count and method (issue 3): ``synthetic:tensile?size=1024x1024&fps=50&frames=N`` (Mono8,
N = 150 by default), subset 21, integer search ``improved-wso`` seeded by the
previous frame (radius 2), for 400, 1,000 and 2,500 points, with the
improved surface fit and with IC-GN as the sub-pixel method. Every case is one
session of ``livedic run`` (``stream.session.session.Session``, its config built with
run's defaults, as ``livedic run --viewer none --progress off --record ...``
gives it), so the benchmark measures exactly what a user gets: acquisition
thread, bounded queue (4 frames, drop the oldest), tracker, recorder (ON, into
a temporary folder deleted afterwards), no viewer. The numbers are the
session's summary (what ``--summary-json`` writes):

* fps tracked = frames tracked / (last result - first arrival);
* drops = frames the queue discarded because the tracker was behind;
* latency = result ready - frame capture on the simulated camera's clock
  (queue wait + delivery hold-up + tracking), reference frame left out;
* tracking = time inside ``Tracker.track`` per frame;
* error = RMS distance to the simulator's exact displacement (ok points).

Three extra rows for IC-GN at 1,000 points: ``--no-record`` (what the
recording costs), ``--search none`` (IC-GN started from the previous frame's
result, no integer search; lost points are still re-found by the re-find
search: what the seeding search costs; with IC-GN the default improved-WSO
seed search runs only for the points IC-GN leaves doubtful, see
``dic.tracking``) and an unpaced source (``pace=0``:
frames as fast as the pipeline takes them, the queue blocks instead of
dropping) whose fps is the highest rate this machine sustains with recording.

The simulator renders every frame before the session starts (it is not part of
the measured time); that rendering time is printed on its own. Target on the
2-core lab machine: 1,000 points with IC-GN at >= 50 fps, latency p99 <= 30 ms
and no drops.

Every session computes strain and two virtual extensometers, as the main job
``livedic run --gauge-length 400`` does (400 px at 1 MP; 0.75 x the ROI height
on smaller images): the strain stage is the session's first sink, in the
tracker thread, after ``Tracker.track``. Its cost per frame (the summary's
``strain`` block: p50 and p99) is printed for every case, as milliseconds and
as a share of the tracking time in the same session, with the issue-11 target:
strain + two extensometers <= 2 ms per frame at 1,000 points (judged on the
p50 of the 1,000-point IC-GN case; its p99 is printed next to it).

Every session also publishes its strain (``livedic run --publish udp://127.0.0.1:PORT``,
``stream.publish``) to a UDP socket this process reads in a thread (``StrainOutReceiver``),
and the strain-out latency is printed per case, from the tracker's result (the moment
``Tracker.track`` returns, ``FrameResult.done_ns``: the strain stage, which computes what
is sent, is inside it) to

* the send returning (``sendto``, in the tracker thread; the session's own number);
* the datagram's arrival in the receiving socket (the kernel's receive timestamp,
  ``SO_TIMESTAMPNS``, on Linux): when a controller reading that socket could have it;
* the receiving thread's read returning (this process: it waits for the GIL the tracker
  thread holds, so it is an upper bound on what a controller in its own process sees).

The issue-13 target: p99 <= 5 ms at 50 fps on loopback, judged on the arrival in the
socket (the thread's read where the kernel gives no timestamp) of the 1,000-point IC-GN case.
"""

import json
import math
import os
import platform
import shutil
import socket
import struct
import sys
import tempfile
import threading
import time

from livedic.dic import DEFAULT_SUBSET
from livedic.dic.search import DEFAULT_SEARCH

POINT_COUNTS = (400, 1000, 2500)
METHODS = ("improved-surface-fit", "icgn")
TARGET_POINTS = 1000
TARGET_METHOD = "icgn"
TARGET_FPS = 50.0
TARGET_P99_MS = 25.0
TARGET_STRAIN_MS = 2.0
TARGET_STRAIN_OUT_P99_MS = 5.0
GAUGE_LENGTH_PX = 400.0       # the main job's --gauge-length (setup.sh, README)


def _load():
    try:
        return "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        return "load average n/a"


def _num(value, fmt, missing="n/a"):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return missing
    return format(value, fmt)


# Linux: SO_TIMESTAMPNS (= SCM_TIMESTAMPNS) stamps each datagram with its arrival (CLOCK_REALTIME, timespec).
_SO_TIMESTAMPNS = 35


class StrainOutReceiver:
    """A UDP socket on 127.0.0.1 that a thread reads the session's ``--publish`` datagrams from.

    Per datagram it keeps the frame, its arrival in the socket (the kernel's timestamp, on the
    monotonic clock; None where the system gives none) and when the thread's read returned.
    """

    def __init__(self):
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.socket.bind(("127.0.0.1", 0))
        self.socket.settimeout(0.05)
        self.kernel_stamps = sys.platform.startswith("linux")
        if self.kernel_stamps:
            try:
                self.socket.setsockopt(socket.SOL_SOCKET, _SO_TIMESTAMPNS, 1)
            except OSError:
                self.kernel_stamps = False
        self.uri = f"udp://127.0.0.1:{self.socket.getsockname()[1]}"
        self.received = []                  # (datagram, arrival ns or None, read ns), monotonic clock
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, name="livedic bench strain-out receiver", daemon=True)
        self._thread.start()

    def _read(self):
        while not self._stop.is_set():
            try:
                data, ancillary, _, _ = self.socket.recvmsg(65536, socket.CMSG_SPACE(16))
            except (socket.timeout, BlockingIOError):
                continue
            read_ns = time.monotonic_ns()
            offset = _wall_minus_monotonic_ns()
            arrival = None
            for level, kind, payload in ancillary:
                if level == socket.SOL_SOCKET and kind == _SO_TIMESTAMPNS and len(payload) >= 16:
                    seconds, nanoseconds = struct.unpack("qq", payload[:16])
                    arrival = seconds * 1_000_000_000 + nanoseconds - offset
            self.received.append((data, arrival, read_ns))

    def stop(self):
        """Stop reading (what arrived is read first); returns [(frame, arrival ns or None, read ns)]."""
        time.sleep(0.1)
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.socket.close()
        return [(json.loads(data)["frame"], arrival, read) for data, arrival, read in self.received]


def _wall_minus_monotonic_ns(tries=5):
    """The wall clock - the monotonic clock, now (ns): the kernel's receive stamp is on the wall clock.

    Read between two monotonic readings, kept from the try where they were closest: a preemption
    between the readings would shift it by the time lost. Read per datagram, so a step of the wall
    clock between datagrams does not matter.
    """
    best = None
    for _ in range(tries):
        before = time.monotonic_ns()
        wall = time.time_ns()
        after = time.monotonic_ns()
        if best is None or after - before < best[0]:
            best = (after - before, wall - (before + after) // 2)
        if after - before < 20_000:
            break
    return best[1]


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


def _label(row):
    label = row["subpixel"]
    notes = []
    if row.get("search", DEFAULT_SEARCH) != DEFAULT_SEARCH:
        notes.append(f"search {row['search']}")
    if not row["record"]:
        notes.append("no-record")
    if not row["paced"]:
        notes.append("unpaced")
    return label + (f" ({', '.join(notes)})" if notes else "")


HEADER = (f"{'points':>6s} {'method':34s} {'fps in':>6s} {'fps out':>7s} {'tracked':>9s} {'drops':>5s} "
          f"{'lat p50':>8s} {'lat p99':>8s} {'trk p50':>8s} {'trk p99':>8s} {'POI/s':>9s} {'err RMS':>8s}")


def format_row(row):
    s = row["summary"]
    if row["error"] and not s:
        return f"{row['points_wanted']:>6d} {_label(row):34s} failed: {row['error']}"
    paced = row["paced"]

    def ms(key, meaningful=True):
        value = s.get(key)
        if not meaningful:
            return f"{'n/a*':>8s}"
        return f"{_num(value, '6.1f')}ms" if _num(value, '6.1f') != "n/a" else f"{'n/a':>8s}"

    return (f"{s.get('points', row['points_wanted']):>6d} {_label(row):34s} "
            f"{_num(row['fps_offered'], '6.0f') if paced else 'max':>6s} {_num(s.get('fps'), '7.1f'):>7s} "
            f"{s.get('frames', 0):>4d}/{s.get('acquired', 0):<4d} {s.get('dropped', 0):>5d} "
            f"{ms('latency_p50_ms', paced)} {ms('latency_p99_ms', paced)} "
            f"{ms('processing_p50_ms')} {ms('processing_p99_ms')} "
            f"{_num(s.get('poi_per_s'), '9,.0f'):>9s} {_num(s.get('error_rms_px'), '8.4f'):>8s}")


def judge_target(row, *, quick=False):
    """(passed: bool, one line) for the issue-3 target on ``row`` (1,000 points, IC-GN, recorded, paced)."""
    variant = "" if row is None or row.get("search", DEFAULT_SEARCH) == DEFAULT_SEARCH else f" --search {row['search']}"
    if row is None or not row["summary"]:
        why = row["error"] if row else "the case did not run"
        return False, (f"FAIL  target 1,000 points IC-GN{variant} >= {TARGET_FPS:g} fps, p99 <= {TARGET_P99_MS:g} ms, "
                       f"no drops: {why}")
    s = row["summary"]
    offered = row["fps_offered"] or 0.0
    dropped = int(s.get("dropped") or 0)
    every_frame = s.get("frames") == s.get("acquired") and dropped == 0
    p99 = s.get("latency_p99_ms")
    checks = [
        (offered >= TARGET_FPS, f"offered {offered:g} fps {'>=' if offered >= TARGET_FPS else '<'} {TARGET_FPS:g}"),
        (every_frame, f"{s.get('frames')}/{s.get('acquired')} frames tracked, {dropped} dropped "
                      f"(fps out {_num(s.get('fps'), '.1f')}: the reference set-up, {_num(s.get('setup_ms'), '.0f')} ms, "
                      "and the last frame's latency are in its denominator)"),
        (p99 is not None and math.isfinite(p99) and p99 <= TARGET_P99_MS,
         f"latency p99 {_num(p99, '.1f')} ms {'<=' if p99 is not None and p99 <= TARGET_P99_MS else '>'} "
         f"{TARGET_P99_MS:g} ms"),
    ]
    passed = all(ok for ok, _ in checks)
    where = f"{row['size']}x{row['size']}, {s.get('points')} points, {row['search']} + IC-GN, recording on"
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  target 1,000 points IC-GN{variant} >= {TARGET_FPS:g} fps, "
                    f"p99 <= {TARGET_P99_MS:g} ms, no drops ({where}): "
                    + "; ".join(("ok " if ok else "NOT ") + text for ok, text in checks) + note)


def strain_cost_line(row):
    """One line: the strain stage's cost per frame in ``row``'s session, in ms and against its tracking time."""
    s = row["summary"]
    strain = s.get("strain") if s else None
    if not strain:
        return f"  {row['points_wanted']:>6d} {_label(row):34s} n/a ({row['error'] or 'no strain in the summary'})"
    p50, p99, track = strain.get("strain_ms_p50"), strain.get("strain_ms_p99"), s.get("processing_p50_ms")
    share = f"{100 * p50 / track:5.1f} %" if p50 is not None and track else "  n/a"
    names = ", ".join(strain.get("extensometers") or {}) or "none"
    return (f"  {s.get('points', row['points_wanted']):>6d} {_label(row):34s} p50 {_num(p50, '6.3f')} ms, "
            f"p99 {_num(p99, '6.3f')} ms; {share} of tracking (p50 {_num(track, '.1f')} ms); extensometers {names}")


def judge_strain_cost(row, *, quick=False):
    """(passed: bool, one line) for the issue-11 target on ``row`` (1,000 points IC-GN): strain <= 2 ms per frame."""
    strain = (row or {}).get("summary", {}).get("strain") if row else None
    if not strain or strain.get("strain_ms_p50") is None:
        why = (row or {}).get("error") or "no strain cost in the summary"
        return False, f"FAIL  target strain + two extensometers <= {TARGET_STRAIN_MS:g} ms per frame at 1,000 points: {why}"
    s = row["summary"]
    p50, p99 = strain["strain_ms_p50"], strain["strain_ms_p99"]
    track = s.get("processing_p50_ms")
    passed = p50 <= TARGET_STRAIN_MS
    names = list(strain.get("extensometers") or {})
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  target strain + two extensometers <= {TARGET_STRAIN_MS:g} ms per "
                    f"frame at 1,000 points: p50 {p50:.3f} ms (p99 {_num(p99, '.3f')} ms, "
                    f"{'also' if p99 is not None and p99 <= TARGET_STRAIN_MS else 'NOT'} <= {TARGET_STRAIN_MS:g}), "
                    f"{_num(100 * p50 / track if track else None, '.1f')} % of the tracking time (p50 "
                    f"{_num(track, '.1f')} ms) in the same session ({row['size']}x{row['size']}, {s.get('points')} "
                    f"points, IC-GN, window {strain.get('strain_window')}, VSG {_num(strain.get('vsg_px'), 'g')} px, "
                    f"extensometers {', '.join(names) or 'none'}, axial {row['gauge_length']:g} px){note}")


def strain_out_line(row):
    """One line: ``row``'s strain-out latency (result -> sent, -> in the receiving socket, -> read by a thread)."""
    out = row.get("strain_out")
    if not out:
        return f"  {row['points_wanted']:>6d} {_label(row):34s} n/a ({row['error'] or 'nothing published'})"
    s = row["summary"]

    def pair(key):
        return f"p50 {_num(out[key + '_p50_ms'], '.2f')} ms, p99 {_num(out[key + '_p99_ms'], '.2f')} ms"
    failed = f", {out['failed']} NOT sent" if out["failed"] else ""
    arrival = (f"in the socket {pair('arrival')}; " if out["arrival_p99_ms"] is not None
               else "in the socket n/a (no kernel timestamps); ")
    return (f"  {s.get('points', row['points_wanted']):>6d} {_label(row):34s} {out['sent']}/{out['frames']} sent"
            f"{failed}, {out['received']} received; result -> sent {pair('sent')} (before the publisher "
            f"{pair('upstream')}; in it {pair('stage')}); {arrival}read by a thread {pair('read')}")


def judge_strain_out(row, *, quick=False):
    """(passed: bool, one line) for the issue-13 target on ``row``: strain-out latency p99 <= 5 ms at 50 fps."""
    title = (f"target strain-out latency p99 <= {TARGET_STRAIN_OUT_P99_MS:g} ms at {TARGET_FPS:g} fps on loopback "
             f"(1,000 points IC-GN)")
    out = (row or {}).get("strain_out")
    if not out or not out.get("sent"):
        why = (row or {}).get("error") or "nothing was published"
        return False, f"FAIL  {title}: {why}"
    if out["arrival_p99_ms"] is not None:
        judged, p50, where = out["arrival_p99_ms"], out["arrival_p50_ms"], "in the receiving socket (kernel timestamp)"
    else:
        judged, p50, where = out["read_p99_ms"], out["read_p50_ms"], "read by a thread of this process"
    offered = row["fps_offered"] or 0.0
    passed = judged is not None and judged <= TARGET_STRAIN_OUT_P99_MS and offered >= TARGET_FPS
    all_sent = out["received"] == out["sent"] == out["frames"]
    note = "  [quick mode: not the 1 MP configuration of the target]" if quick else ""
    return passed, (f"{'PASS' if passed else 'FAIL'}  {title}: result -> {where} p99 {_num(judged, '.2f')} ms "
                    f"(p50 {_num(p50, '.2f')} ms); result -> send returned p99 {_num(out['sent_p99_ms'], '.2f')} ms; "
                    f"{out['received']} datagrams for {out['frames']} tracked frames"
                    f"{'' if all_sent else ' (NOT one per frame)'}; offered {offered:g} fps "
                    f"({row['size']}x{row['size']}, {row['summary'].get('points')} points, {row['search']} + IC-GN, "
                    f"recording on){note}")


def _fit_cost(rows):
    """Least-squares tracking p50 = a + b * points over ``rows``: (a ms, b us/point) or None."""
    pts = [(r["summary"].get("points"), r["summary"].get("processing_p50_ms")) for r in rows if r["summary"]]
    pts = [(n, ms) for n, ms in pts if n and ms is not None and math.isfinite(ms)]
    if len({n for n, _ in pts}) < 2:
        return None
    import numpy as np
    n = np.array([p[0] for p in pts], dtype=float)
    ms = np.array([p[1] for p in pts], dtype=float)
    b, a = np.polyfit(n, ms, 1)
    return float(a), float(b) * 1e3


def explain_limits(rows, fps):
    """Lines saying what bounds the rate and the latency (from the summaries of this run)."""
    lines = []
    budget = 1e3 / fps if fps else float("nan")
    by_key = {(r["points_wanted"], r["subpixel"], r["record"], r["paced"]): r for r in rows
              if r["search"] == DEFAULT_SEARCH}
    for method in METHODS:
        paced_rows = [r for r in rows if r["subpixel"] == method and r["record"] and r["paced"]
                      and r["search"] == DEFAULT_SEARCH]
        fit = _fit_cost(paced_rows)
        if fit is not None:
            a, b = fit
            lines.append(f"  {method}: tracking p50 ~ {a:.1f} ms per frame + {b:.1f} us per point "
                         f"(fit over {len(paced_rows)} point counts{'; noisy: negative intercept' if a < 0 else ''}) "
                         f"-> 1,000 points ~ {a + b:.1f} ms, budget at {fps:g} fps is {budget:.1f} ms")
    target = by_key.get((TARGET_POINTS, TARGET_METHOD, True, True))
    if target and target["summary"]:
        s = target["summary"]
        p50 = s.get("processing_p50_ms")
        if p50:
            lines.append(f"  1,000 points IC-GN: tracking p50 {p50:.1f} ms / p99 {_num(s.get('processing_p99_ms'), '.1f')} ms"
                         f" per frame -> at most ~{1e3 / p50:.0f} fps from tracking alone; "
                         f"frame delivery delay p99 {_num(s.get('delivery_delay_p99_ms'), '.1f')} ms "
                         "(capture -> the acquisition thread has it; it grows when that thread waits for the GIL)")
            p99 = s.get("latency_p99_ms")
            if p99 is not None and p50 > 1e3 / (target["fps_offered"] or TARGET_FPS):
                lines.append(f"  tracking is slower than the frame period, so frames queue up: latency "
                             f"(p99 {p99:.1f} ms) is mostly queue wait, and once the queue is full it drops frames")
    norec = by_key.get((TARGET_POINTS, TARGET_METHOD, False, True))
    if target and norec and target["summary"] and norec["summary"]:
        t, n = target["summary"], norec["summary"]
        lines.append(f"  recording: tracking p50 {_num(t.get('processing_p50_ms'), '.1f')} ms with it vs "
                     f"{_num(n.get('processing_p50_ms'), '.1f')} ms without; latency p99 "
                     f"{_num(t.get('latency_p99_ms'), '.1f')} vs {_num(n.get('latency_p99_ms'), '.1f')} ms; "
                     f"drops {t.get('dropped')} vs {n.get('dropped')}")
    unseeded = next((r for r in rows if r["search"] == "none" and r["points_wanted"] == TARGET_POINTS
                     and r["subpixel"] == TARGET_METHOD and r["record"] and r["paced"]), None)
    if target and unseeded and target["summary"] and unseeded["summary"]:
        t, n = target["summary"], unseeded["summary"]
        if t.get("processing_p50_ms") is not None and n.get("processing_p50_ms") is not None:
            lines.append(f"  seeding search: {DEFAULT_SEARCH} r2 (run only for points IC-GN from the previous result leaves "
                         f"doubtful) + IC-GN takes {t['processing_p50_ms']:.1f} ms per frame (p50), IC-GN from the "
                         f"previous result alone (--search none) {n['processing_p50_ms']:.1f} ms: the integer search "
                         f"costs {t['processing_p50_ms'] - n['processing_p50_ms']:.1f} ms; error "
                         f"RMS {_num(t.get('error_rms_px'), '.4f')} vs {_num(n.get('error_rms_px'), '.4f')} px, "
                         f"re-found points {t.get('refound')} vs {n.get('refound')}")
    unpaced = by_key.get((TARGET_POINTS, TARGET_METHOD, True, False))
    if unpaced and unpaced["summary"]:
        lines.append(f"  highest sustained rate, 1,000 points IC-GN with recording (unpaced source, blocking queue): "
                     f"{_num(unpaced['summary'].get('fps'), '.1f')} fps")
    return lines


# ----------------------------------------------------------------------------- the main job, stage by stage

MAIN_JOB_ARGS = ("--gauge-length", "400", "--load", "synthetic")      # setup.sh's main job, after "livedic run"
TARGET_ERROR_RMS_PX = 0.012
TARGET_MAX_FPS = {None: 200.0, 2000: 100.0}     # unpaced, everything on: points (None: the main job's) -> fps
# The stage rows of the per-frame table, in pipeline order: (stage name in the summary, label, thread).
STAGE_ROWS = (
    ("prepare", "preparing the new frame", "tracking"),
    ("kernel", "IC-GN kernel, all points", "tracking"),
    ("seeded_search", "seeded search (doubtful points)", "tracking"),
    ("refind", "re-find search (lost points)", "tracking"),
    ("gates", "quality gates", "tracking"),
    ("reference_update", "reference updates", "tracking"),
    ("tracker", "= tracker total", "tracking"),
    ("strain", "strain field", "tracking"),
    ("extensometers", "extensometers", "tracking"),
    ("publish", "strain out (publish)", "tracking"),
    ("force", "force", "tracking"),
    ("Poisson's ratio", "Poisson's ratio", "output"),
    ("record frame", "recording the frame", "acquisition"),
    ("record results", "recording the results", "output"),
    ("view", "Rerun view: handing the frame over", "output"),
    ("view drawing", "Rerun view: drawing", "view process"),
    ("progress", "progress line", "output"),
)


def main_job_args(*, uri, record_path, rrd_path, publish_uri, n_points=None, gauge_length=GAUGE_LENGTH_PX):
    """``livedic run`` words of the main job on ``uri``, its outputs in the bench's folder, strain out to a socket
    (``gauge_length``: the main job's 400 px, shorter on a smaller image)."""
    words = ["run", *MAIN_JOB_ARGS, "--gauge-length", f"{gauge_length:g}", "--source", uri, "--record", record_path, "--viewer", "save", rrd_path,
             "--progress", "off", "--publish", publish_uri]
    if n_points is not None:
        words += ["--n-points", str(n_points)]
    return words


def run_main_job_case(*, size, frames, fps, paced=True, n_points=None, workdir, echo=None):
    """The main job (``livedic run --gauge-length 400 --load synthetic``: recording, Rerun .rrd, strain, two
    extensometers, force), plus strain out to a socket, on ``synthetic:tensile`` at ``fps`` (or unpaced:
    frames as fast as taken, a blocking queue); returns a row dict like ``run_case``'s."""
    from livedic.stream.cli import build_parser
    from livedic.stream.session.config import SessionConfig
    from livedic.stream.output.files import json_text

    tag = f"main-{n_points or 'default'}-{'paced' if paced else 'unpaced'}-{fps:g}"
    uri = f"synthetic:tensile?size={size}x{size}&fps={fps:g}&frames={frames}"
    if not paced:
        # a sustained rate needs more frames than are worth rendering: cycle through the rendered ones
        uri = (f"synthetic:tensile?size={size}x{size}&fps={fps:g}&frames={UNPACED_CYCLES * frames}&loop={frames}"
               f"&pace=0")
    record_path = os.path.join(workdir, f"{tag}.mcap")
    receiver = StrainOutReceiver()
    words = main_job_args(uri=uri, record_path=record_path, rrd_path=os.path.join(workdir, f"{tag}.rrd"),
                          publish_uri=receiver.uri, n_points=n_points, gauge_length=gauge_length_for(size))
    if not paced:
        words += ["--drop", "block"]
    row = dict(case=tag, points_wanted=n_points, paced=paced, fps_offered=fps if paced else None, size=size,
               frames_offered=frames if paced else UNPACED_CYCLES * frames, error=None, render_s=None,
               summary={}, command="livedic " + " ".join(words[:1] + list(MAIN_JOB_ARGS)))
    said = []
    try:
        session, row["error"] = run_one_session(lambda: SessionConfig.from_args(build_parser().parse_args(words)),
                                                said)
    finally:
        receiver.stop()
    if session is not None:
        row["render_s"] = session.render_seconds
        if session.summary() is not None:
            row["summary"] = json.loads(json_text(session.summary()))
    if echo is not None:
        echo("\n".join(said + ([session.summary_text()] if session is not None and session.summary_text() else [])))
    for name in os.listdir(workdir):
        if name.startswith(tag):
            os.remove(os.path.join(workdir, name))
    return row


UNPACED_CYCLES = 4          # an unpaced case tracks this many times the rendered frames
MAIN_JOB_FRAMES = 300       # the main job's own length (livedic run's default)


def _main_label(row):
    points = row["summary"].get("points") or row["points_wanted"]
    if row["paced"]:
        return f"main job at {row['fps_offered']:g} fps"
    return f"unpaced, {points:,} points" if points else "unpaced"


MAIN_HEADER = (f"{'case':28s} {'fps in':>6s} {'fps out':>7s} {'tracked':>9s} {'drops':>5s} {'lat p50':>8s} "
               f"{'lat p99':>8s} {'img out':>7s} {'behind':>6s} {'err RMS':>8s}")


def format_main_row(row):
    s = row["summary"]
    if not s:
        return f"{_main_label(row):28s} failed: {row['error']}"
    paced = row["paced"]
    lat = (lambda key: f"{_num(s.get(key), '6.1f')}ms") if paced else (lambda key: f"{'n/a*':>8s}")
    return (f"{_main_label(row):28s} {_num(row['fps_offered'], '6.0f') if paced else 'max':>6s} "
            f"{_num(s.get('fps'), '7.1f'):>7s} {s.get('frames', 0):>4d}/{s.get('acquired', 0):<4d} "
            f"{s.get('dropped', 0):>5d} {lat('latency_p50_ms')} {lat('latency_p99_ms')} "
            f"{s.get('viewer_images_left_out') or 0:>7d} {s.get('output_backlog_max') or 0:>6d} "
            f"{_num(s.get('error_rms_px'), '8.4f'):>8s}")


def stage_table(rows):
    """Lines: p50/p99 ms per frame of each stage (rows of ``STAGE_ROWS``), one column per case."""
    width = 15
    lines = [f"{'stage (thread)':46s}" + "".join(f"{_main_label(r)[:width - 1]:>{width}s}" for r in rows),
             f"{'':46s}" + "".join(f"{'p50/p99 ms':>{width}s}" for _ in rows)]
    for key, label, thread in STAGE_ROWS:
        cells = []
        for row in rows:
            stage = (row["summary"].get("stages") or {}).get(key)
            cells.append(f"{_num(stage['p50_ms'], '.2f')}/{_num(stage['p99_ms'], '.2f')}" if stage else "-")
        if any(cell != "-" for cell in cells):
            lines.append(f"{label + ' (' + thread + ')':46s}" + "".join(f"{cell:>{width}s}" for cell in cells))
    ratios = [tracker_kernel_ratio(row) for row in rows]
    lines.append(f"{'tracker / IC-GN kernel, p50 (goal <= 1.5x)':46s}"
                 + "".join(f"{_num(ratio, '.2f') + 'x' if ratio else 'n/a':>{width}s}" for ratio in ratios))
    return lines


def tracker_kernel_ratio(row):
    """The tracker's p50 per frame over its IC-GN kernel's p50 (same points, same frames, same run), or None."""
    stages = row["summary"].get("stages") or {}
    tracker, kernel = stages.get("tracker"), stages.get("kernel")
    if not tracker or not kernel or not kernel["p50_ms"]:
        return None
    return tracker["p50_ms"] / kernel["p50_ms"]


def judge_main_job(row):
    """(passed, one line): every frame tracked, none dropped, every frame's fields drawn, p99 <= 25 ms, RMS <= 0.012 px."""
    title = (f"target {_main_label(row)}: every frame tracked, 0 dropped, fields in every frame, latency p99 <= "
             f"{TARGET_P99_MS:g} ms, error RMS <= {TARGET_ERROR_RMS_PX:g} px")
    s = row["summary"]
    if not s:
        return False, f"FAIL  {title}: {row['error'] or 'the case did not run'}"
    p99, rms = s.get("latency_p99_ms"), s.get("error_rms_px")
    checks = [
        (s.get("frames") == s.get("acquired") == row["frames_offered"] and not s.get("dropped"),
         f"{s.get('frames')}/{s.get('acquired')} tracked, {s.get('dropped')} dropped"),
        (p99 is not None and p99 <= TARGET_P99_MS, f"p99 {_num(p99, '.1f')} ms"),
        (rms is not None and rms <= TARGET_ERROR_RMS_PX, f"RMS {_num(rms, '.4f')} px"),
        (True, f"camera image left out of the view in {s.get('viewer_images_left_out') or 0} frames (fields drawn "
               f"in all; output thread at most {s.get('output_backlog_max')} behind)"),
    ]
    passed = all(ok for ok, _ in checks)
    return passed, f"{'PASS' if passed else 'FAIL'}  {title}: " + "; ".join(
        ("ok " if ok else "NOT ") + text for ok, text in checks)


def judge_max_rate(row):
    """(passed, one line): the highest sustained rate, unpaced, everything on, against its goal."""
    goal = TARGET_MAX_FPS.get(row["points_wanted"])
    s = row["summary"]
    label = _main_label(row)
    if not s:
        return False, f"FAIL  goal {label} >= {goal:g} fps: {row['error'] or 'the case did not run'}"
    fps = s.get("fps")
    passed = fps is not None and fps >= goal
    return passed, (f"{'PASS' if passed else 'FAIL'}  goal {label} (everything on) >= {goal:g} fps: "
                    f"{_num(fps, '.1f')} fps sustained over {s.get('frames')} frames, tracker p50 "
                    f"{_num((s.get('stages') or {}).get('tracker', {}).get('p50_ms'), '.1f')} ms")


TARGET_TRACKER_RATIO = 1.5


def judge_tracker_ratio(row):
    """(passed, one line): the tracker's p50 per frame against its IC-GN kernel's, same points, same run."""
    ratio = tracker_kernel_ratio(row)
    stages = row["summary"].get("stages") or {}
    if ratio is None:
        return False, f"FAIL  goal tracker / IC-GN kernel <= {TARGET_TRACKER_RATIO:g}x ({_main_label(row)}): no timings"
    passed = ratio <= TARGET_TRACKER_RATIO
    return passed, (f"{'PASS' if passed else 'FAIL'}  goal tracker / IC-GN kernel <= {TARGET_TRACKER_RATIO:g}x "
                    f"({_main_label(row)}, {row['summary'].get('points')} points): {ratio:.2f}x (tracker p50 "
                    f"{stages['tracker']['p50_ms']:.2f} ms, kernel p50 {stages['kernel']['p50_ms']:.2f} ms)")


def run_main_job_benchmark(*, size, frames, say, echo=None):
    """The main job at 50 and 100 fps and unpaced for its points and for 2,000: table, stage table, verdicts."""
    cases = [dict(fps=TARGET_FPS), dict(fps=2 * TARGET_FPS), dict(fps=TARGET_FPS, paced=False),
             dict(fps=TARGET_FPS, paced=False, n_points=2000)]
    rows = []
    workdir = tempfile.mkdtemp(prefix="livedic-bench-main-")
    try:
        say(f"the main job, everything on (livedic run {' '.join(MAIN_JOB_ARGS)}: recording, Rerun .rrd, strain, "
            f"two extensometers, force; plus strain out to a UDP socket), synthetic:tensile {size}x{size}, "
            f"{frames} frames paced, {UNPACED_CYCLES * frames} unpaced:")
        say(MAIN_HEADER)
        say("-" * len(MAIN_HEADER))
        for case in cases:
            row = run_main_job_case(size=size, frames=frames, workdir=workdir, echo=echo, **case)
            rows.append(row)
            say(format_main_row(row))
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    say("columns: img out = frames whose camera image the view left out (it was behind; fields and numbers are "
        "drawn for every frame); behind = the most results waiting for the output thread (recording, view)")
    say("per frame, each stage (the thread it runs in; '-' where it did not run; the reference frame left out):")
    for line in stage_table(rows):
        say(line)
    verdicts = ([judge_main_job(row) for row in rows if row["paced"]]
                + [judge_max_rate(row) for row in rows if not row["paced"]] + [judge_tracker_ratio(rows[0])])
    for _, line in verdicts:
        say(line)
    return rows, verdicts


def run_live_benchmark(*, quick=False, frames=None, fps=TARGET_FPS, size=None, points=None, methods=METHODS,
                       extra_rows=True, threads=1, log=print, echo_sessions=False):
    """Run the cases, print the table, the target verdict and the limits; returns a result dict.

    Parameters
    ----------
    quick : bool
        512x512, 40 frames, 1,000 points only (CI and tests).
    frames, fps, size, points :
        Frames per case (default 150, quick 40), rate of the simulated camera,
        image side (default 1024, quick 512), point counts (default 400, 1000, 2500).
    extra_rows : bool
        Add the IC-GN 1,000-point rows without recording and with an unpaced source.
    log : callable
        Receives each output line.

    Returns
    -------
    dict
        ``rows`` (one dict per case), ``target_passed``, ``target_line``, ``lines`` (everything printed).
    """
    import numba

    size = size or (512 if quick else 1024)
    main_frames = frames or (40 if quick else MAIN_JOB_FRAMES)
    frames = frames or (40 if quick else 150)
    points = tuple(points or ((TARGET_POINTS,) if quick else POINT_COUNTS))
    printed = []

    def say(text=""):
        printed.append(text)
        log(text)

    say(f"livedic bench live: synthetic:tensile {size}x{size} Mono8 rendered ahead, subset {DEFAULT_SUBSET}, {DEFAULT_SEARCH} search "
        f"r2, queue 4 drop-oldest, 1 numba thread for the main job and {threads} for the pipeline's table")
    say(f"machine: {os.cpu_count()} CPU cores, {platform.machine()}, numba {numba.__version__}; "
        f"{_load()} at start{'  [quick mode]' if quick else ''}")
    main_rows, main_verdicts = run_main_job_benchmark(
        size=size, frames=main_frames, say=say,
        echo=(lambda text: [say("    " + line) for line in text.splitlines()]) if echo_sessions else None)
    say()
    say(f"the pipeline by point count and method: {frames} frames per case at {fps:g} fps (paced), recording on, "
        f"no view, {threads} numba thread(s):")
    cases = [dict(n_points=n, subpixel=m) for n in points for m in methods]
    if extra_rows and TARGET_METHOD in methods and TARGET_POINTS in points:
        cases.append(dict(n_points=TARGET_POINTS, subpixel=TARGET_METHOD, record=False))
        cases.append(dict(n_points=TARGET_POINTS, subpixel=TARGET_METHOD, search="none"))
        cases.append(dict(n_points=TARGET_POINTS, subpixel=TARGET_METHOD, paced=False))
    rows = []
    workdir = tempfile.mkdtemp(prefix="livedic-bench-live-")
    started = time.perf_counter()
    try:
        say(HEADER)
        say("-" * len(HEADER))
        for case in cases:
            row = run_case(size=size, frames=frames, fps=fps, threads=threads, workdir=workdir,
                           echo=(lambda text: [say("    " + line) for line in text.splitlines()])
                           if echo_sessions else None, **case)
            rows.append(row)
            say(format_row(row))
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    say("columns: fps in = rate of the simulated camera; fps out = frames tracked / (last result - first "
        "arrival); tracked = tracked/acquired frames; lat = capture -> result; trk = time in Tracker.track; "
        "err = RMS vs exact displacement")
    if any(not r["paced"] for r in rows):
        say("  * unpaced row: frames wait in a full, blocking queue, so latency means nothing there")
    renders = [r["render_s"] for r in rows if r["render_s"] is not None]
    if renders:
        say(f"rendering the simulated frames (before the clock, not measured): {sum(renders) / len(renders):.1f} s "
            f"per case for {frames} frames ({1e3 * sum(renders) / len(renders) / frames:.0f} ms per frame), "
            f"{sum(renders):.0f} s in all")
    for row in rows:
        if row["error"]:
            say(f"error in {row['points_wanted']} points {_label(row)}: {row['error']}")
    target_row = next((r for r in rows if r["points_wanted"] == TARGET_POINTS and r["subpixel"] == TARGET_METHOD
                       and r["record"] and r["paced"] and r["search"] == DEFAULT_SEARCH), None)
    passed, line = judge_target(target_row, quick=quick)
    say(line)
    unseeded = next((r for r in rows if r["points_wanted"] == TARGET_POINTS and r["subpixel"] == TARGET_METHOD
                     and r["record"] and r["paced"] and r["search"] == "none"), None)
    variant_line = None
    if unseeded is not None:
        variant_passed, variant_line = judge_target(unseeded, quick=quick)
        say(variant_line)
    say(f"strain + two extensometers per frame (the session's first sink, in the tracker thread; axial "
        f"{rows[0]['gauge_length']:g} px and transverse through P0):" if rows else "strain: no case ran")
    for row in rows:
        say(strain_cost_line(row))
    strain_passed, strain_line = judge_strain_cost(target_row, quick=quick)
    say(strain_line)
    say("strain out (--publish udp://127.0.0.1:PORT, one JSON datagram per tracked frame, read by a thread of this "
        "process; latency from the tracker's result, the strain stage included):")
    for row in rows:
        say(strain_out_line(row))
    strain_out_passed, strain_out_line_text = judge_strain_out(target_row, quick=quick)
    say(strain_out_line_text)
    say("what limits it:")
    for text in explain_limits(rows, fps):
        say(text)
    say(f"total {time.perf_counter() - started:.0f} s; {_load()} at end")
    return dict(rows=rows, main_rows=main_rows, main_verdicts=main_verdicts, target_passed=passed,
                target_line=line, variant_line=variant_line,
                strain_passed=strain_passed, strain_line=strain_line, strain_out_passed=strain_out_passed,
                strain_out_line=strain_out_line_text, lines=printed)
