"""Tests of stream/session/stereo.py through whole stereo sessions on the simulated rig (``stereo:`` of two
``synthetic:stereo`` views): a pure out-of-plane translation reads no strain in space while one camera alone reads
W/distance; both views and the 3D points are recorded; the summary says the rig, the match and the pairing; a
rig file with one camera, a one-camera file or no calibration with a real pair are one line each."""

import json

import numpy as np
import pytest

from livedic.acquire.recording.reader import read_results, read_session
from livedic.acquire.recording.source import McapSource
from livedic.acquire.simulator.lens import Lens
from livedic.dic.stereo import SURFACE_MEASURE
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.calibration import write_calibration
from livedic.stream.session.config import PointsConfig, SessionConfig, ViewerConfig
from livedic.stream.session.session import Session
from livedic.stream.stages.strain import StrainConfig

VIEW = "synthetic:stereo?view={}&frames=4&size=384x384&focal=3000&strain=0&neck=0&w0=0.5&noise=0.5&pace=0"
PAIR = f"stereo:{VIEW.format('left')},{VIEW.format('right')}"


def _run(source, tmp_path, **config):
    config = SessionConfig(source=source, viewer=ViewerConfig("none"), record=str(tmp_path / "s.mcap"),
                           warm_up=False, strain=StrainConfig(gauge_length=10.0), points=PointsConfig(step=12),
                           **config)
    with Session(config) as session:
        session.prepare()
        session.start()
        session.run()
    return session


@pytest.fixture(scope="module")
def translated(tmp_path_factory):
    return _run(PAIR, tmp_path_factory.mktemp("stereo"))


def test_an_out_of_plane_translation_reads_no_strain_in_space(translated):
    """The coupon moves 0.5 mm away from the cameras (along its normal, which bisects the rig): the 3D points move
    0.5 mm, the extensometers in space read < 1e-4, where one camera would read -0.5 / 300.5 = -1.66e-3."""
    summary = translated.summary()
    stereo, strain = summary["stereo"], summary["strain"]
    assert stereo["match"]["matched"] == stereo["match"]["points"] > 300
    assert stereo["last"]["ok"] >= 0.98 * stereo["last"]["points"]
    for name in ("axial", "transverse"):
        reading = strain["extensometers"][name]
        assert reading["ok"] and abs(reading["eng_strain"]) < 1e-4, (name, reading)
    assert strain["extensometers"]["axial"]["L0_mm"] == pytest.approx(10.0, rel=0.05)
    last = translated.loop.tracker.last_points
    moved = np.linalg.norm(last.displacement[last.ok], axis=1)
    assert np.mean(moved) == pytest.approx(0.5, abs=0.005) and np.std(moved) < 0.005
    assert np.nanmax(np.abs(translated.strain.last_strain.e1)) < 2e-3       # noise of a 65 px VSG, no trend
    text = translated.summary_text()
    assert "stereo     rig: baseline" in text and "L0 " in text and "mm in space" in text
    assert "pairs: 4 made, 0 dropped" in text


def test_both_views_and_the_3d_points_are_recorded(translated):
    path = translated.config.record
    left, right = list(McapSource(path)), list(McapSource(path, view="right"))
    assert len(left) == len(right) == 4 and not np.array_equal(left[1].image, right[1].image)
    results = read_results(path)
    last = results[-1].stereo
    assert set(last) >= {"x_mm", "y_mm", "z_mm", "u_mm", "v_mm", "w_mm", "stereo_status", "right_x", "right_y"}
    ok = last["stereo_status"] == 0
    assert np.mean(ok) > 0.98
    moved = np.sqrt(last["u_mm"][ok] ** 2 + last["v_mm"][ok] ** 2 + last["w_mm"][ok] ** 2)
    assert np.mean(moved) == pytest.approx(0.5, abs=0.005)
    assert np.all(np.abs(last["z_mm"][ok] - 300.0) < 30.0)          # the coupon near the rig's working distance
    session = read_session(path)                  # the strain settings as measured: on the surface, no 2D calibration
    assert session["strain_measure"] == SURFACE_MEASURE and session["calibration"] is None


def test_calibrations_that_do_not_fit_the_source_are_one_line(tmp_path):
    rig = StereoRig.symmetric(Lens((384, 384), focal_px=3000.0), Lens((384, 384), focal_px=3000.0),
                              distance_mm=300.0, angle_deg=25.0)
    path = tmp_path / "rig.json"
    write_calibration(path, rig.calibration())
    with pytest.raises(ValueError, match="stereo rig's calibration .two cameras. but the source is one camera"):
        _run("synthetic:translate?frames=2&size=128x128&pace=0", tmp_path, rig=rig.calibration())
    with pytest.raises(ValueError, match="a stereo source needs the rig's calibration"):
        _run("stereo:synthetic:translate?frames=2&size=128x128&pace=0,synthetic:translate?frames=2&size=128x128"
             "&pace=0&seed=3", tmp_path)
    assert json.loads(path.read_text())["stereo"] is True


STATIC = 4
STATIC_VIEW = "synthetic:stereo?view={}&frames=2&size=192x192&focal=1500&strain=0&neck=0&noise=1&pace=0"


def test_static_pairs_give_the_noise_floor_in_space_live_and_from_the_recording(tmp_path):
    """--static-frames N with a simulated stereo pair: both views render N static frames, the summary's floor has
    U, V, W (the depth ~1 / tan(12.5 deg) = 4.5 x the in-plane noise), and the recording gives the same table."""
    from livedic.acquire.recording.reader import Recording
    from livedic.stream.stages.noise_floor import recorded_noise_floor
    session = _run(f"stereo:{STATIC_VIEW.format('left')},{STATIC_VIEW.format('right')}", tmp_path,
                   static_frames=STATIC)
    floor = session.summary()["noise_floor"]
    assert floor["static_frames"] == STATIC and floor["frames_used"] == list(range(1, STATIC + 1))
    rows = {row["quantity"]: row for row in floor["table"]}
    assert [row["quantity"] for row in floor["table"]][:5] == ["u", "v", "U", "V", "W"]
    for name in ("U", "V", "W", "exx", "axial", "transverse"):
        assert rows[name]["status"] == "ok" and rows[name]["temporal_sd_mean"] > 0.0, rows[name]
    assert rows["W"]["temporal_sd_mean"] / rows["U"]["temporal_sd_mean"] == pytest.approx(4.5, rel=0.3)
    text = session.summary_text().splitlines()
    assert sum(line.split()[:2] in (["U", "mm"], ["V", "mm"], ["W", "mm"]) for line in text) == 3
    assert any("pairs: 6 made" in line for line in text)           # the test's 2 frames and the 4 static ones
    recorded = recorded_noise_floor(Recording(session.config.record))
    assert recorded["frames_used"] == floor["frames_used"]
    again = {row["quantity"]: row for row in recorded["table"]}
    for name in ("U", "V", "W", "exx", "axial"):
        for key in ("spatial_sd", "temporal_sd_mean", "mean"):
            if rows[name][key] is not None:
                assert again[name][key] == pytest.approx(rows[name][key], rel=1e-4, abs=1e-9), (name, key)
