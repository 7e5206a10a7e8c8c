"""Numbers a user can quote (issue 19, item 6): Poisson's ratio over the elastic range, % ok over every placed
point, a short extensometer warned about, processing time (not latency) for files, a full disk one warning.

The simulator's law is known: Poisson's ratio 0.3 elastic, 0.5 plastic (``acquire.simulator.model``).
"""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from livedic.acquire.recording.reader import read_events
from livedic.stream.session.config import PointsConfig, SessionConfig, ViewerConfig
from livedic.stream.session.session import Session, drop_policy, is_live
from livedic.stream.stages.strain import StrainConfig

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
# 150 frames: the elastic part is the first 23 (to 0.4 % axial strain), the E fit's range about 7 of them
TENSILE = "synthetic:tensile?frames=150&size=384x512&pace=0"
NU_ELASTIC = 0.3


def _session(source, *, strain=None, load=None, points=None, record=None):
    config = SessionConfig(source=source, viewer=ViewerConfig("none"), record=record, warm_up=False,
                           strain=strain or StrainConfig(), load=load, points=points or PointsConfig())
    with Session(config) as session:
        session.prepare()
        session.start()
        session.run()
    return session


@pytest.fixture(scope="module", params=["synthetic", None], ids=["force", "no-force"])
def tensile_session(request):
    return _session(TENSILE, strain=StrainConfig(gauge_length=250), load=request.param)


# --------------------------------------------------------------------------- Poisson's ratio

def test_poisson_ratio_is_fitted_over_the_elastic_range_and_labelled_so(tensile_session):
    strain = tensile_session.summary()["strain"]
    nu = strain["poisson_ratio"]
    assert nu["reason"] is None and 0 < nu["stderr"] < 0.05
    assert abs(nu["value"] - NU_ELASTIC) <= 4 * nu["stderr"], nu
    first, last = nu["frames"]
    assert nu["label"] == (f"Poisson's ratio (elastic, frames {first}-{last}, axial strain "
                           f"{nu['label'].split('axial strain ')[1]}")
    # the law is elastic to 0.4 %; the plastic strain then grows 0.05 / (0.45 x 149) a frame: the end of the
    # linear part is seen within 3 frames (a 70 px transverse is noisy), the proportional limit at once
    assert nu["axial_strain_range"][1] <= 0.004 + 3 * 0.05 / (0.45 * 149)
    assert nu["basis"] == ("force" if tensile_session.load_stage is not None else "linear_part")
    # the plastic contraction ratio: in the summary JSON, labelled so, never in the text
    plastic = strain["plastic_contraction_ratio"]
    assert plastic["label"].startswith("plastic contraction ratio") and "Poisson" not in plastic["label"]
    assert abs(plastic["value"] - 0.5) < 0.05, plastic
    text = tensile_session.summary_text()
    line = [row for row in text.splitlines() if row.startswith("  Poisson")]
    words = ("below the proportional limit, where force vs axial strain is linear" if nu["basis"] == "force" else
             "the initial linear part of transverse vs axial")
    assert line == [f"  Poisson    {nu['label']} = {nu['value']:.3f} +- {nu['stderr']:.3f} (range: {words})"]
    assert "plastic" not in text and "last frame" not in text
    json.dumps(tensile_session.summary(), allow_nan=True)


def test_a_test_too_short_for_its_elastic_part_has_no_poisson_ratio_and_says_why():
    """14 frames: two before yield. No number rather than the plastic slope labelled elastic."""
    session = _session("synthetic:tensile?frames=14&size=384x512&pace=0", strain=StrainConfig(gauge_length=200))
    nu = session.summary()["strain"]["poisson_ratio"]
    assert nu["value"] != nu["value"] and nu["reason"], nu          # NaN with a reason
    assert f"Poisson    Poisson's ratio (elastic" in session.summary_text()
    assert f": n/a ({nu['reason']})" in session.summary_text()


# --------------------------------------------------------------------------- % ok over every placed point

def test_ok_counts_every_placed_point_and_says_which_were_never_trackable():
    """The whole image as ROI: the points on the simulator's flat background can never be tracked."""
    session = _session("synthetic:tensile?frames=6&size=256x384&pace=0",
                       points=PointsConfig(roi=(0, 0, 256, 384), step=16))
    summary = session.summary()
    never = summary["points_never_trackable"]
    n = summary["points"]
    assert never["count"] > 0.2 * n and set(never["by_status"]) <= {"FLAT_REFERENCE", "POOR_TEXTURE",
                                                                     "OUTSIDE_REFERENCE"}
    assert sum(never["by_status"].values()) == never["count"]
    stats = session.stats
    assert stats.points_placed == n * summary["frames"]
    assert summary["ok_fraction"] == pytest.approx(stats.points_ok / (n * summary["frames"]))
    assert summary["ok_fraction"] <= (n - never["count"]) / n < summary["ok_fraction_of_trackable"] + 1e-12
    text = session.summary_text()
    assert f"{100 * summary['ok_fraction']:.1f} % ok over all of them" in text
    from livedic.dic.status import Status
    reasons = ", ".join(f"{count} {Status[name].description}" for name, count in never["by_status"].items())
    assert f"{never['count']} never trackable ({reasons})" in text


# --------------------------------------------------------------------------- a short extensometer in a session

def test_a_narrow_roi_warns_about_its_automatic_transverse_once_and_records_it(tmp_path):
    record = tmp_path / "narrow.mcap"
    messages = []
    config = SessionConfig(source="synthetic:tensile?frames=4&size=384x512&pace=0", viewer=ViewerConfig("none"),
                           record=str(record), warm_up=False, strain=StrainConfig(gauge_length=250),
                           points=PointsConfig(roi=(162, 56, 60, 400), step=7, p0=(192.0, 256.0)))
    with Session(config, say=messages.append) as session:
        session.prepare()
        session.start()
        session.run()
    transverse = session.strain.extensometers[1]
    assert transverse.name == "transverse" and transverse.length_px < 3 * 21
    warned = [m for m in messages if m.startswith("warning: extensometer transverse")]
    assert len(warned) == 1 and "shorter than 3 subsets (63 px)" in warned[0] and "microstrain" in warned[0]
    events = [e for e in read_events(str(record)) if e.kind == "extensometer_noise"]
    assert [e.message for e in events if "transverse" in e.message] == [warned[0][len("warning: "):]]
    assert all(e.level == "warning" for e in events)


# --------------------------------------------------------------------------- files: processing, not latency

def test_a_file_source_reports_processing_time_and_a_paced_one_latency(tmp_path):
    record = tmp_path / "paced.mcap"
    paced = _session("synthetic:tensile?frames=5&size=192x256&fps=50", record=str(record))
    assert paced.summary()["live"] and paced.summary()["latency_p50_ms"] > 0
    assert "  latency    p50" in paced.summary_text()
    replayed = _session(f"mcap:{record}")
    summary = replayed.summary()
    assert summary["live"] is False and summary["latency_p50_ms"] is None and summary["latency_from"] is None
    assert summary["processing_p50_ms"] > 0 and summary["fps"] > 0
    text = replayed.summary_text()
    assert "  latency" not in text and "  processing tracking p50" in text and "fps, " in text and "achieved" in text
    assert "(no latency: the source is not paced by a clock)" in text


def test_the_source_says_whether_it_is_live(tmp_path):
    import cv2

    from livedic.acquire.sources import open_source
    from livedic.stream.pipeline.frame_queue import BLOCK, DROP_OLDEST
    folder = tmp_path / "images"
    folder.mkdir()
    for i in range(2):
        cv2.imwrite(str(folder / f"f{i}.png"), np.full((16, 16), 100 + i, np.uint8))
    cases = [(f"images:{folder}", {}, False), (f"images:{folder}", {"realtime": 1}, True),
             ("synthetic:tensile?frames=2&size=64x96&pace=0", {}, False),
             ("synthetic:tensile?frames=2&size=64x96", {}, True)]
    for uri, options, live in cases:
        with open_source(uri, **options) as source:
            assert is_live(source) is live, (uri, options)
            assert drop_policy("auto", source) == (DROP_OLDEST if live else BLOCK)
    assert not is_live(object())            # a source without the property (a replay's frames) is a file


# --------------------------------------------------------------------------- a full disk: one warning

def _tmpfs_run(tmp_path, size_kb, fill, *options, keep=None):
    """``livedic run`` with a tmpfs of ``size_kb`` KiB mounted at tmp_path/full in a mount namespace of its own
    (``unshare``: root, or user namespaces), filled first when ``fill``, ``keep`` (a name in it) copied out to
    tmp_path/kept afterwards (the tmpfs ends with the namespace); skipped where mounting is not allowed."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("unshare is not installed")
    full = tmp_path / "full"
    full.mkdir()
    probe = subprocess.run([unshare, "--mount", "--map-root-user", "sh", "-c",
                            f"mount -t tmpfs -o size=64k tmpfs '{full}'"], capture_output=True)
    if probe.returncode:
        pytest.skip(f"cannot mount a tmpfs in a mount namespace here: {probe.stderr.decode().strip()}")
    filling = f"dd if=/dev/zero of='{full}/filler' bs=4096 2>/dev/null; " if fill else ""
    command = [sys.executable, "-m", "livedic.stream.cli", "run", "--progress", "off", *options]
    copy = f"cp '{full}/{keep}' '{tmp_path}/kept' 2>/dev/null; " if keep else ""
    script = f"mount -t tmpfs -o size={size_kb}k tmpfs '{full}' || exit 99; {filling}\"$@\"; rc=$?; {copy}exit $rc"
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([unshare, "--mount", "--map-root-user", "sh", "-c", script, "sh", *command],
                          capture_output=True, text=True, cwd=str(tmp_path), env=env, timeout=300)
    return done, full


def test_a_full_disk_for_the_summary_json_is_one_warning_and_the_summary_is_printed(tmp_path):
    done, full = _tmpfs_run(tmp_path, 256, True, "--source", "synthetic:tensile?frames=4&size=128x192&pace=0",
                            "--n-points", "30", "--viewer", "none", "--no-record",
                            "--summary-json", str(tmp_path / "full" / "summary.json"))
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].startswith("livedic: warning: the summary JSON was not written: ")
    assert "No space left on device" in warnings[0] and "Traceback" not in done.stderr
    assert "livedic run: synthetic:tensile" in done.stdout and "frames     14 tracked" in done.stdout   # 4 of the test after 10 static
    # the namespace's tmpfs is gone with it: nothing of it is left here (and nothing half-written was there)
    assert not (full / "summary.json").exists()


def test_a_full_disk_for_the_rerun_file_is_one_warning_the_session_goes_on(tmp_path):
    # a paced 2 s test whose .rrd (~100 kB a frame) fills a 2 MiB tmpfs: written each second, it fails part way
    done, _ = _tmpfs_run(tmp_path, 2048, False, "--source", "synthetic:tensile?frames=40&size=256x384&fps=20",
                         "--n-points", "60", "--no-record", "--viewer", "save", str(tmp_path / "full" / "view.rrd"),
                         "--summary-json", str(tmp_path / "summary.json"), keep="view.rrd")
    assert done.returncode == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and warnings[0].startswith("livedic: warning: Rerun view file stopped: cannot write ")
    assert "No space left on device" in warnings[0] and "the session goes on" in warnings[0]
    assert "ERROR" not in done.stderr and "Traceback" not in done.stderr
    assert "tracked of 50 acquired" in done.stdout and "STOPPED EARLY" in done.stdout
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] + summary["dropped"] == 50 and "No space left on device" in summary["rerun_error"]
    kept = tmp_path / "kept"
    size = kept.stat().st_size
    assert 0 < size <= 2048 * 1024 and f"keeps its first {size / 1e6:.1f} MB" in warnings[0]
    # Rerun's viewer reads a cut stream up to the cut, as its `rerun rrd print` shows
    rerun = os.path.join(os.path.dirname(sys.executable), "rerun")
    shown = subprocess.run([rerun, "rrd", "print", str(kept)], capture_output=True, text=True, timeout=60)
    assert shown.stdout.count("/camera/image") >= 2, shown.stderr


def test_a_report_without_a_transverse_extensometer_says_so():
    from livedic.dic.tensile.properties import tensile_properties
    from livedic.stream.export.report import report_json, report_markdown
    strain = np.linspace(0.0, 0.01, 20)
    report = report_json(tensile_properties(strain, 200e3 * strain), {"area_mm2": 20.0, "gauge_length_px": 200.0},
                         {"recording": "r.mcap", "truncated": False, "load": "csv:f.csv", "load_offset_s": 0.0,
                          "frames": 20, "frames_with_force": 20, "strain": "", "generated_at": "now"})
    for key in ("poisson_ratio", "plastic_contraction_ratio"):
        assert report[key]["value"] is None and report[key]["reason"] == "no axial and transverse extensometer pair"
    json.dumps(report, allow_nan=False)
    assert "| Poisson's ratio (elastic) | n/a |" in report_markdown(report, "plot.png", "r.mcap")


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="needs Linux's sched_setaffinity and two CPUs")
def test_cores_split_is_said_in_the_summary_and_every_cpu_comes_back():
    every = os.sched_getaffinity(0)
    config = SessionConfig(source="synthetic:translate?frames=6&size=96x96&du=0.3&dv=0.2&pace=0",
                           viewer=ViewerConfig("none"), record=None, warm_up=False, cores="split")
    with Session(config) as session:
        session.prepare()
        session.start()
        session.run()
    assert session.summary()["cores"].startswith(f"tracking thread on CPU {max(every)}")
    assert "tracking thread on CPU" in session.summary_text()
    assert os.sched_getaffinity(0) == every
    assert SessionConfig(source="synthetic:translate").cores == "split"        # the default: a CPU for the tracker
