"""The main job of ``livedic bench live`` (``livedic run --gauge-length 400 --load synthetic``), stage by stage.

Paced at 50 and 100 fps and unpaced: a table of cases, a per-stage table, and the issue-20 verdicts.
"""

import json
import os
import shutil
import tempfile

from livedic.bench.live.cases import GAUGE_LENGTH_PX, TARGET_FPS, TARGET_P99_MS, gauge_length_for, run_one_session
from livedic.bench.live.receiver import StrainOutReceiver
from livedic.bench.live.verdicts import number_text

MAIN_JOB_ARGS = ("--gauge-length", "400", "--load", "synthetic")      # setup.sh's main job, after "livedic run"
TARGET_ERROR_RMS_PX = 0.012
TARGET_MAX_FPS = {None: 200.0, 2000: 100.0}     # unpaced, everything on: points (None: the main job's) -> fps
# The stage rows of the per-frame table, in pipeline order: (stage name in the summary, label, thread).
STAGE_ROWS = (
    ("prepare ahead", "prefiltering the new frame ahead", "acquisition"),
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
    ("record frame", "recording the frame", "frame recorder"),
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
        row["frames_offered"] += session.preparation.static_frames   # the noise floor's, before the test's
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
    lat = (lambda key: f"{number_text(s.get(key), '6.1f')}ms") if paced else (lambda key: f"{'n/a*':>8s}")
    return (f"{_main_label(row):28s} {number_text(row['fps_offered'], '6.0f') if paced else 'max':>6s} "
            f"{number_text(s.get('fps'), '7.1f'):>7s} {s.get('frames', 0):>4d}/{s.get('acquired', 0):<4d} "
            f"{s.get('dropped', 0):>5d} {lat('latency_p50_ms')} {lat('latency_p99_ms')} "
            f"{s.get('viewer_images_left_out') or 0:>7d} {s.get('output_backlog_max') or 0:>6d} "
            f"{number_text(s.get('error_rms_px'), '8.4f'):>8s}")


def stage_table(rows):
    """Lines: p50/p99 ms per frame of each stage (rows of ``STAGE_ROWS``), one column per case."""
    width = 15
    lines = [f"{'stage (thread)':46s}" + "".join(f"{_main_label(r)[:width - 1]:>{width}s}" for r in rows),
             f"{'':46s}" + "".join(f"{'p50/p99 ms':>{width}s}" for _ in rows)]
    for key, label, thread in STAGE_ROWS:
        cells = []
        for row in rows:
            stage = (row["summary"].get("stages") or {}).get(key)
            cells.append(f"{number_text(stage['p50_ms'], '.2f')}/{number_text(stage['p99_ms'], '.2f')}" if stage else "-")
        if any(cell != "-" for cell in cells):
            lines.append(f"{label + ' (' + thread + ')':46s}" + "".join(f"{cell:>{width}s}" for cell in cells))
    ratios = [tracker_kernel_ratio(row) for row in rows]
    lines.append(f"{'tracker / IC-GN kernel, p50 (goal <= 1.5x)':46s}"
                 + "".join(f"{number_text(ratio, '.2f') + 'x' if ratio else 'n/a':>{width}s}" for ratio in ratios))
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
        (p99 is not None and p99 <= TARGET_P99_MS, f"p99 {number_text(p99, '.1f')} ms"),
        (rms is not None and rms <= TARGET_ERROR_RMS_PX, f"RMS {number_text(rms, '.4f')} px"),
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
                    f"{number_text(fps, '.1f')} fps sustained over {s.get('frames')} frames, tracker p50 "
                    f"{number_text((s.get('stages') or {}).get('tracker', {}).get('p50_ms'), '.1f')} ms")


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
