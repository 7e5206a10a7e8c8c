"""``livedic bench replay``: what writing the output costs, then sequential vs Dask (``--workers 1``, ``2``).

Setup: one recording (given, or made here by ``livedic run`` on the simulated tensile test
with its defaults, ``--reference-update auto`` among them: the reference moves as the coupon
stretches, and the parallel replays measure again what they measured ahead of each move).

What writing costs. The recording is replayed sequentially (``stream.replay.replay.replay``, in this
process) four times, after one untimed replay (numba's kernels loaded, the file read once): with
no output (tracking, strain and the comparison with the recording only), then writing the CSV as
livedic formatted it before ``stream.output.csv_text`` (numpy's float -> str cell by cell:
``per_cell_csv_rows``, the baseline), the CSV as ``livedic replay -o OUT.csv`` writes it now, and
the Parquet file of ``-o OUT.parquet``, each through the command's own staged file in a temporary
folder. Per output: frames/s and its ratio to the rate with no output, and the time inside the
writer per frame (formatting and writing the rows, the file's closing included) and its share of
the replay's time; on a shared machine the time inside the writer is the steadier measure, the
rates move with the load. The two CSV files must be the same bytes (said when not).

Then the same recording on a LocalCluster of 1 and of 2 worker processes (1 thread each:
``stream.replay.parallel_replay.dask_client``), the largest also with ``--shared-path`` (the workers
read the frames from the file instead of receiving them from the replaying process); the
sequential row is the CSV replay above. Each
cluster is started and warmed up before it is timed (every worker tracks a small frame pair:
numba's cached kernels load on first use), so the times are the replay's, not the start's;
the start is reported apart. Every mode writes the CSV as ``livedic replay -o OUT.csv`` does.

Per mode: wall time, frames/s and the ratio to the sequential rate (sequential: its time per
frame is all of it, tracking and CSV lines); the tracker's own time per frame inside the tasks
and the CSV lines' (strain and formatting on the worker); the overhead per frame, (wall x
worker threads - those two) / frames: the worker time that went to anything else (scheduling, moving
the image, waiting for the client to read and submit the next frames); the replaying process's
own time per frame (wall minus its waits for results: reading and submitting frames, strain,
comparison, CSV), the serial part that bounds the rate whatever the number of workers; the
frames measured again (measured ahead against a reference that then moved: part of the
overhead); and on
each cluster a
no-op task's round trip (one at a time: the latency a frame pays) and the cost per task of a
batch of no-op tasks carrying a frame-sized uint8 image (the scheduler's throughput). The
replays' verdicts against the recording must be the same in every mode.
"""

import json
import os
import tempfile
import time

import numpy as np

from livedic.stream.output.csv_text import scalar_text
from livedic.stream.replay.rows import CsvRows, rows_output

NOOP_TASKS = 100
QUICK = dict(frames=30, size="256x256", points=300, workers=(1, 2))


def parse_workers(text):
    """``"1,2"`` -> (1, 2): the worker counts to time (``"0"`` -> (): no cluster); ValueError (one line) otherwise."""
    if str(text).strip() == "0":
        return ()
    try:
        counts = tuple(int(part) for part in str(text).split(","))
    except ValueError:
        counts = ()
    if not counts or any(count < 1 for count in counts):
        raise ValueError(f"--workers {text!r}: give worker counts like 1,2 (each >= 1), or 0 for none")
    return counts


def _noop(image=None):
    return 0 if image is None else int(image.shape[0])


def per_cell_csv_rows(columns, n):
    """The CSV lines as livedic formatted them before ``stream.output.csv_text``: numpy's float -> str cell by cell.

    The same text as ``stream.output.csv_text.csv_rows`` (a test holds them equal), ~4x its time: kept here
    only as the baseline the benchmark measures the writers against.
    """
    if n == 0:
        return ""
    texts = [_per_cell_texts(values, n) for values in columns.values()]
    return "\n".join(map(",".join, zip(*texts))) + "\n"


def _per_cell_texts(values, n):
    array = np.asarray(values)
    if array.ndim == 0:
        return [scalar_text(array.item())] * n
    if array.dtype == bool:
        return np.where(array, "1", "0").tolist()
    if array.dtype.kind in "OUS":
        return [scalar_text(value) for value in array.tolist()]
    if array.dtype.kind in "iu":
        return array.astype(str).tolist()
    return array.astype(np.float64).astype(str).tolist()   # numpy's float -> str: the shortest repr


class PerCellCsv(CsvRows):
    """The replay CSV with its lines formatted by ``per_cell_csv_rows`` (the baseline)."""

    def lines_of(self, rows):
        return per_cell_csv_rows(rows.columns, rows.n)


class TimedWriter:
    """A replay output writer (``on_rows``) that adds up the time spent in it."""

    def __init__(self, write):
        self.write = write
        self.csv_text = write.csv_text
        self.seconds = 0.0

    def __call__(self, rows):
        started = time.perf_counter()
        self.write(rows)
        self.seconds += time.perf_counter() - started


def warm_tracker():
    """Track a small shifted frame once: numba's kernels (search, IC-GN) loaded in this process."""
    from livedic.dic.speckle import SpecklePattern, render
    from livedic.dic.tracking import Tracker
    pattern = SpecklePattern((96, 96), n_speckles=150, seed=1)
    tracker = Tracker(render(pattern), [(48, 48), (40, 56)], subpixel="icgn")
    tracker.track(render(pattern, (0.4, -0.3)))
    return True


def noop_overhead(client, image, tasks=NOOP_TASKS):
    """(round trip of one no-op task at a time, s; cost per task of ``tasks`` no-op tasks with ``image``, s)."""
    one = []
    for _ in range(10):
        started = time.perf_counter()
        client.submit(_noop, pure=False).result()
        one.append(time.perf_counter() - started)
    started = time.perf_counter()
    futures = [client.submit(_noop, image, pure=False) for _ in range(tasks)]
    client.gather(futures)
    batch = (time.perf_counter() - started) / tasks
    return float(np.median(one)), batch


def make_recording(folder, *, frames, size, points, log):
    """A ``livedic run`` recording of the simulated tensile test (run's defaults) in ``folder``."""
    from livedic.stream.cli import main
    path = os.path.join(folder, "bench-replay.mcap")
    # --static-frames 0: the frames replayed are the test's ``frames``, no noise-floor frames before them
    code = main(["run", "--source", f"synthetic:tensile?size={size}&frames={frames}&pace=0", "--static-frames", "0",
                 "--record", path,
                 "--viewer", "none", "--n-points", str(points), "--progress", "off"])
    if code != 0:
        raise RuntimeError(f"livedic run could not make the bench recording (exit {code})")
    log(f"recording: {frames} frames of {size}, {points} points wanted: {path}")
    return path


def _mode(name, report, wall, threads):
    frames = report.frames
    compute = report.parallel.compute_seconds if report.parallel is not None else None
    row = {"mode": name, "frames": frames, "wall_s": wall, "frames_per_s": frames / wall if wall > 0 else float("nan"),
           "worker_threads": threads, "verdict": report.verdict(), "agreement": report.agreement.name}
    if compute is not None:
        rows_s = report.parallel.rows_seconds
        row["tracking_ms_per_frame"] = 1e3 * compute / frames
        row["csv_ms_per_frame"] = 1e3 * rows_s / frames
        row["overhead_ms_per_frame"] = 1e3 * (wall * threads - compute - rows_s) / frames
        row["image_bytes_per_frame"] = report.parallel.image_bytes / frames
        row["seed_bytes_per_frame"] = report.parallel.seed_bytes / frames
        # what the replaying process itself spends per frame (reading, submitting, strain, comparison, CSV):
        # the serial part, which bounds the rate whatever the number of workers
        row["client_ms_per_frame"] = 1e3 * (wall - report.parallel.wait_seconds) / frames
        row["reference_moves_and_fractures"] = report.parallel.segments - 1
        row["frames_measured_again"] = report.parallel.resubmitted
    else:
        row["tracking_ms_per_frame"] = 1e3 * wall / frames
    return row


WRITERS = (("no output", None), ("CSV, per-cell (before)", "before.csv"), ("CSV", "replay.csv"),
           ("Parquet", "replay.parquet"))


def writer_rows(path, folder, *, log=print):
    """The sequential replay of ``path`` with each output of ``WRITERS`` (written in ``folder``): the rows,
    and the CSV ``replay``'s report and wall time (the sequential mode of the parallel comparison)."""
    from livedic.stream.replay.replay import replay

    replay(path)             # untimed: the session stages' numba kernels loaded, the file in the page cache
    rows, csv_run = [], None
    for name, file_name in WRITERS:
        started = time.perf_counter()
        if file_name is None:
            report = replay(path)
            writing = 0.0
        else:
            target = os.path.join(folder, file_name)
            with rows_output(target) as writer:
                timed = TimedWriter(PerCellCsv(writer.out) if name.startswith("CSV, per-cell") else writer)
                report = replay(path, on_rows=timed)
                closing = time.perf_counter()
            writing = timed.seconds + time.perf_counter() - closing
        wall = time.perf_counter() - started
        if name == "CSV":
            csv_run = (report, wall)
        rows.append({"output": name, "frames": report.frames, "wall_s": wall, "frames_per_s": report.frames / wall,
                     "ms_per_frame": 1e3 * wall / report.frames, "writing_ms_per_frame": 1e3 * writing / report.frames,
                     "writing_share": writing / wall, "agreement": report.agreement.name,
                     "file_mb": os.path.getsize(target) / 1e6 if file_name else None})
        log(f"{name}: {report.frames} frames x {report.points} points in {wall:.2f} s")
    base = rows[0]["frames_per_s"]
    for row in rows:
        row["ratio_vs_no_output"] = row["frames_per_s"] / base
    with open(os.path.join(folder, "before.csv"), "rb") as before:
        with open(os.path.join(folder, "replay.csv"), "rb") as now:
            same = before.read() == now.read()
    for row in rows[1:3]:
        row["same_text_as_before"] = same
    return rows, csv_run


def run_replay_benchmark(*, recording=None, frames=60, size="1024x1024", points=2000, workers=(1, 2), output=None,
                         quick=False, log=print):
    """Replay one recording with each output, sequentially and on LocalClusters of ``workers`` processes.

    Parameters
    ----------
    recording : str, optional
        A livedic recording; default: one made here (``frames``, ``size`` "WxH", ``points`` wanted).
    workers : sequence of int
        Worker processes of each LocalCluster timed (none: the sequential replays only).
    output : str, optional
        Folder for ``replay.json``.
    quick : bool
        ``QUICK``'s smaller recording (when none is given) and worker counts (a minute).
    log : callable
        Takes each line of the report.

    Returns
    -------
    rows : list of dict
        One per mode: sequential, then each cluster.
    writers : list of dict
        One per output of ``WRITERS`` (sequential).
    """
    from livedic.stream.replay.parallel_replay import dask_client
    from livedic.stream.replay.replay import replay

    if quick:
        frames, size, points, workers = QUICK["frames"], QUICK["size"], QUICK["points"], QUICK["workers"]
    with tempfile.TemporaryDirectory(prefix="livedic-bench-replay-") as folder:
        path = recording or make_recording(folder, frames=frames, size=size, points=points, log=log)
        from livedic.acquire.recording.source import McapSource
        with McapSource(path) as source:
            image = np.ascontiguousarray(next(iter(source)).image)
        warm_tracker()
        writers, (report, wall) = writer_rows(path, folder, log=log)
        rows = [_mode("sequential", report, wall, 1)]
        for count in workers:
            started = time.perf_counter()
            with dask_client(count) as client:
                client.run(warm_tracker)
                start_s = time.perf_counter() - started
                one, batch = noop_overhead(client, image)
                address = client.scheduler.address
                for shared in ((None, "") if count == max(workers) else (None,)):
                    name = f"--workers {count}" + (" --shared-path" if shared is not None else "")
                    started = time.perf_counter()
                    with rows_output(os.path.join(folder, "parallel.csv")) as writer:
                        report = replay(path, cluster=address, shared_path=shared, on_rows=writer)
                    row = _mode(name, report, time.perf_counter() - started, count)
                    row.update(cluster_start_s=start_s, noop_round_trip_ms=1e3 * one,
                               noop_batch_ms_per_task=1e3 * batch)
                    rows.append(row)
                    log(f"{name}: cluster up and warm in {start_s:.1f} s, replay {row['wall_s']:.2f} s")
    base = rows[0]["frames_per_s"]
    for row in rows:
        row["ratio_vs_sequential"] = row["frames_per_s"] / base
    for line in format_writers(writers) + format_rows(rows):
        log(line)
    if not writers[1]["same_text_as_before"]:
        log("warning: the CSV written now is not the bytes the per-cell formatter wrote")
    close = ("EXACT", "WITHIN_ROUNDING")
    if any(row["agreement"] not in close for row in rows) and len({row["agreement"] for row in rows}) != 1:
        log("warning: the modes do not agree with the recording alike: " + "; ".join(
            f"{row['mode']}: {row['agreement']}" for row in rows))
    if output:
        os.makedirs(output, exist_ok=True)
        with open(os.path.join(output, "replay.json"), "w") as f:
            json.dump({"cpu_count": os.cpu_count(), "writers": writers, "rows": rows}, f, indent=2)
        log(f"wrote {os.path.join(output, 'replay.json')}")
    return rows, writers


def format_writers(writers):
    """The outputs' table: one line per output of ``WRITERS``."""
    lines = [f"{'output (sequential replay)':<26} {'frames/s':>9} {'x none':>6} {'ms/frame':>8} {'writing ms/f':>12} "
             f"{'share':>6} {'file MB':>8}"]
    for row in writers:
        size = f"{row['file_mb']:.1f}" if row["file_mb"] is not None else "-"
        lines.append(f"{row['output']:<26} {row['frames_per_s']:>9.1f} {row['ratio_vs_no_output']:>6.2f} "
                     f"{row['ms_per_frame']:>8.1f} {row['writing_ms_per_frame']:>12.1f} "
                     f"{100 * row['writing_share']:>5.0f}% {size:>8}")
    return lines


def format_rows(rows):
    """The table: one line per mode."""
    lines = [f"{'mode':<26} {'frames/s':>9} {'x seq':>6} {'track ms/f':>10} {'csv ms/f':>8} {'overhead ms/f':>13} "
             f"{'no-op rt ms':>11} {'no-op ms/task':>13} {'client ms/f':>11} {'MB/f sent':>9} {'again':>5}  verdict"]
    for row in rows:
        def num(key, fmt):
            value = row.get(key)
            return format(value, fmt) if value is not None else "-"
        sent = f"{row['image_bytes_per_frame'] / 1e6:.2f}" if "image_bytes_per_frame" in row else "-"
        lines.append(f"{row['mode']:<26} {row['frames_per_s']:>9.1f} {row['ratio_vs_sequential']:>6.2f} "
                     f"{num('tracking_ms_per_frame', '.1f'):>10} {num('csv_ms_per_frame', '.1f'):>8} "
                     f"{num('overhead_ms_per_frame', '.1f'):>13} "
                     f"{num('noop_round_trip_ms', '.2f'):>11} {num('noop_batch_ms_per_task', '.2f'):>13} "
                     f"{num('client_ms_per_frame', '.1f'):>11} "
                     f"{sent:>9} {num('frames_measured_again', 'd'):>5}  {row['agreement']}")
    return lines
