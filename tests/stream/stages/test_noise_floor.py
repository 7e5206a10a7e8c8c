"""The session's noise floor: static frames of the simulator measured as the iDICs guide says, recorded, read back.

The expected displacement noise of a subset with the camera's noise sigma: sigma_u = sigma / sqrt(sum g_x^2) over
the subset (g_x: the image gradient) for the noise of the deformed frame alone (each point's temporal SD: the
reference is the same in every static frame); the reference's own noise adds as much again, fixed per point,
which the spatial SD over points sees: spatial ~ sqrt(2) x temporal (Pan et al. 2009, "Two-dimensional digital
image correlation for in-plane displacement and strain measurement: a review", eq. 27).
"""

import math

import numpy as np
import pytest

from livedic.acquire.recording.reader import Recording
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.session.session import Session
from livedic.stream.stages.noise_floor import recorded_noise_floor
from livedic.stream.stages.strain import StrainConfig
from livedic.stream.stages.stress import RECORDED_FORCE, StressOptions

NOISE = 2.0                 # grey levels (8 bit): well above the rounding's 0.29
STATIC = 8
SOURCE = f"synthetic:tensile?size=256x256&frames=12&pace=0&noise={NOISE}"


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    record = str(tmp_path_factory.mktemp("noise") / "static.mcap")
    config = SessionConfig(source=SOURCE, viewer=ViewerConfig("none"), record=record, warm_up=False,
                           strain=StrainConfig(gauge_length=12, scale=10.0), static_frames=STATIC, load="synthetic")
    with Session(config) as session:
        session.prepare()
        session.start()
        session.run()
    return session


def _rows(summary):
    return {(row["quantity"], row["unit"]): row for row in summary["table"]}


def _expected_temporal_sd(session):
    """sigma / sqrt(sum of g_x^2 over the subset), the median over the points, on the reference image."""
    image = session.preparation.ahead.frame.image.astype(float)
    gx = np.gradient(image, axis=1)
    half = session.config.tracking.subset // 2
    sums = [np.sum(gx[int(y) - half:int(y) + half + 1, int(x) - half:int(x) + half + 1] ** 2)
            for x, y in session.points]
    return NOISE / math.sqrt(np.median(sums))


def test_the_static_frames_are_taken_after_the_reference_and_counted(session):
    summary = session.summary()
    assert session.stats.frames == 12 + STATIC
    floor = summary["noise_floor"]
    assert floor["static_frames"] == STATIC and floor["frames_used"] == list(range(1, STATIC + 1))
    rows = _rows(floor)
    assert list(rows) == [("u", "px"), ("v", "px"), ("u", "mm"), ("v", "mm"), ("exx", "microstrain"),
                          ("eyy", "microstrain"), ("exy", "microstrain"), ("axial", "microstrain"),
                          ("transverse", "microstrain")]
    assert all(row["status"] == "ok" for row in rows.values())
    assert "noise      floor on 8 static frame(s)" in session.summary_text()


def test_the_displacement_noise_floor_is_the_cameras_noise_through_the_subset(session):
    rows = _rows(session.summary()["noise_floor"])
    expected = _expected_temporal_sd(session)
    for component in ("u", "v"):
        row = rows[(component, "px")]
        assert 0.5 * expected < row["temporal_sd_mean"] < 2.0 * expected, (row, expected)
        # the reference's noise, fixed per point, shows in the spatial SD only
        assert 1.1 < row["spatial_sd"] / row["temporal_sd_mean"] < 1.9, row
        # zero mean: each point's fixed error averages out over the points, of which only one in (subset /
        # step)^2 is independent (neighbouring subsets share their pixels)
        independent = row["points"] * (session.preparation.step / session.config.tracking.subset) ** 2
        assert abs(row["mean"]) < 5 * row["spatial_sd"] / math.sqrt(independent), row
        in_mm = rows[(component, "mm")]
        assert in_mm["temporal_sd_mean"] == pytest.approx(row["temporal_sd_mean"] / 10.0)
    for name in ("exx", "eyy", "axial"):
        assert 0 < rows[(name, "microstrain")]["temporal_sd_mean"] < 2000, rows[(name, "microstrain")]


def test_the_recording_gives_the_same_noise_floor(session):
    recording = Recording(session.config.record)
    assert recording.session()["static_frames"] == STATIC
    assert recorded_noise_floor(recording) == session.summary()["noise_floor"]


def test_the_report_shows_the_recorded_noise_floor(session, tmp_path):
    from livedic.stream.export.report import report_recording
    report = report_recording(session.config.record, tmp_path, stress=StressOptions(RECORDED_FORCE, 0.0, 20.0))
    assert report["noise_floor"] == session.summary()["noise_floor"]
    text = (tmp_path / "report.md").read_text()
    assert "## Noise floor" in text and "| quantity | unit | spatial SD |" in text
    u = _rows(report["noise_floor"])[("u", "px")]
    assert f"| u | px | {u['spatial_sd']:.4f} | {u['temporal_sd_mean']:.4f} |" in text


def test_a_replay_measures_the_same_noise_floor(session):
    from livedic.stream.replay.replay import replay
    report = replay(session.config.record)
    assert report.noise_floor["static_frames"] == STATIC
    live, replayed = _rows(session.summary()["noise_floor"]), _rows(report.noise_floor)
    for key, row in live.items():
        for column in ("spatial_sd", "temporal_sd_mean", "mean"):
            if row[column] is not None:
                assert replayed[key][column] == pytest.approx(row[column], rel=1e-6, abs=1e-9), (key, column)


def test_a_dropped_static_frame_is_missing_never_replaced_by_a_moving_one():
    from types import SimpleNamespace

    from livedic.stream.pipeline.stage import Reference
    from livedic.stream.stages.noise_floor import NoiseFloorStage
    rng = np.random.default_rng(5)
    stage = NoiseFloorStage(4)
    stage.on_reference(Reference(frame_index=10, points=np.zeros((50, 2)), roi=(0, 0, 1, 1), step=1, shape=(1, 1)))

    def result(index, shift=0.0):
        u = shift + rng.normal(0.0, 0.01, 50)
        measurement = SimpleNamespace(u=u, v=u.copy(), ok=np.ones(50, bool))
        return SimpleNamespace(is_reference=index == 10, frame=SimpleNamespace(index=index), measurement=measurement,
                               strain=None, extensometers=None, noise_floor=None, dropped_since_last=int(index == 14))

    # frame 13 was dropped by the queue; 15 is the test's first, already moving 5 px
    results = [result(10), result(11), result(12), result(14), result(15, shift=5.0)]
    for item in results:
        stage.on_frame(item)
    summary = stage.summary()
    assert summary["frames_used"] == [11, 12, 14] and results[3].noise_floor is not None
    u = _rows(summary)[("u", "px")]
    assert u["spatial_sd"] < 0.02 and abs(u["mean"]) < 0.01
    assert "floor on 3 static frame(s) after the reference (of 4 asked)" in "\n".join(stage.summary_lines())


def test_a_camera_whose_first_frames_were_never_delivered_takes_the_next_ones():
    """A camera streams while the session is prepared: the frames after the reference (index 0) up to 24 never
    reach the tracker, no queue dropped them; the static window starts at the first delivered frame."""
    from types import SimpleNamespace

    from livedic.stream.pipeline.stage import Reference
    from livedic.stream.stages.noise_floor import NoiseFloorStage
    rng = np.random.default_rng(6)
    stage = NoiseFloorStage(3)
    stage.on_reference(Reference(frame_index=0, points=np.zeros((40, 2)), roi=(0, 0, 1, 1), step=1, shape=(1, 1)))
    for index in (0, 25, 26, 27, 28):
        u = rng.normal(0.0, 0.01, 40)
        stage.on_frame(SimpleNamespace(is_reference=index == 0, frame=SimpleNamespace(index=index), strain=None,
                                       measurement=SimpleNamespace(u=u, v=u.copy(), ok=np.ones(40, bool)),
                                       extensometers=None, noise_floor=None, dropped_since_last=0))
    assert stage.summary()["frames_used"] == [25, 26, 27]
