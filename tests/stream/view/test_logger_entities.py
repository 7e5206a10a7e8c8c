"""Rerun logging: entities written, P0 scalars, periodic flush survives a kill."""

import os
import subprocess
import sys

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.dic.result import Measurement
from livedic.stream.view import colour_scale, entities
from livedic.stream.view.logger import RerunLogger
from livedic.stream.pipeline.frame_result import FrameResult, SessionStats

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))


def _result(i, n=12, shape=(96, 128)):
    rng = np.random.default_rng(i)
    x = np.tile(np.arange(20.0, 20.0 + 8 * 4, 8), 3)[:n]
    y = np.repeat(np.arange(30.0, 30.0 + 8 * 3, 8), 4)[:n]
    ok = np.ones(n, dtype=bool)
    ok[-1] = i % 2 == 0
    m = Measurement(x=x, y=y, u=0.1 * i + 0.01 * x, v=-0.2 * i + 0.0 * y, zncc=0.99 - 0.01 * rng.random(n), ok=ok,
                    status=np.where(ok, 0, 5).astype(np.int8))
    image = rng.integers(0, 4096, size=shape, dtype=np.uint16)
    truth = {"truth": lambda xs, ys: (0.1 * i + 0.01 * xs, -0.2 * i + 0 * ys)}
    frame = Frame(i, i * 20_000_000, image, "Mono12", truth)
    return FrameResult(frame=frame, arrival_ns=1_000_000 * i, done_ns=1_000_000 * i + 3_000_000,
                       processing_ns=2_000_000,
                       measurement=m, is_reference=i == 0, frames_done=i + 1, dropped_total=i // 3,
                       dropped_since_last=1 if i % 3 == 0 and i else 0, queue_depth=1, refound=1 if i == 4 else 0,
                       error_rms_px=0.01, error_max_px=0.02)


def _store_summary(path):
    from rerun.chunk import RrdReader
    return str(RrdReader(str(path)).stream().collect().summary())


def _scalars(path, entity):
    from rerun.chunk import RrdReader
    values = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if str(chunk.entity_path) == entity and not chunk.is_static:
            batch = chunk.to_record_batch()
            values.extend(row[0] if len(row) == 1 else row for row in batch.column("Scalars:scalars").to_pylist())
    return values


def test_none_logs_nothing_and_does_not_import_rerun_lazily():
    logger = RerunLogger("none")
    logger.start(image_shape=(10, 10))
    logger.log_frame(_result(1), SessionStats())
    logger.close()
    assert not logger.enabled and logger.frames_logged == 0


# --------------------------------------------------------------------------- content

def test_saved_recording_holds_every_entity_and_p0_series(tmp_path):
    path = tmp_path / "live.rrd"
    logger = RerunLogger("save", str(path), image_max_side=64)
    logger.start(image_shape=(96, 128), roi=(10, 20, 60, 40), p0_index=0, points=np.zeros((12, 2)), has_truth=True,
                 title="test", source_settings={"model": "tensile"})
    assert logger._scale == 2
    for i in range(8):
        logger.log_frame(_result(i), SessionStats())
    logger.event("a note")
    logger.log_summary("done")
    logger.close()
    text = _store_summary(path)
    for entity in (entities.CAMERA_IMAGE, entities.CAMERA_ROI, entities.CAMERA_P0, entities.FIELD_U,
                   entities.FIELD_V, f"{entities.LEGEND_U}/bar", f"{entities.LEGEND_V}/bar", entities.LIMITS_U,
                   entities.LIMITS_V, entities.LOST, entities.TRACKING, entities.P0,
                   entities.QUALITY, entities.THROUGHPUT, entities.LATENCY, entities.DROPS, entities.ERROR,
                   entities.EVENTS, entities.SUMMARY):
        assert f"/{entity} " in text, entity
    assert "timelines=['frame', 'log_time', 'time']" in text
    p0 = np.array(_scalars(path, "/p0"))
    np.testing.assert_allclose(p0[:, 0], [0.1 * i + 0.2 for i in range(8)], atol=1e-9)   # u
    np.testing.assert_allclose(p0[:, 1], [-0.2 * i for i in range(8)], atol=1e-9)        # v
    assert len(_scalars(path, "/perf/latency")) == 7      # the reference frame has no latency
    assert _scalars(path, "/perf/drops")[-1][0] == 7 // 3
    assert np.array(_scalars(path, "/quality")).shape == (8, 3)


def test_colour_scale_and_display_image():
    logger = RerunLogger("save", "unused.rrd")
    lut = colour_scale.colormap_lut()
    colours = logger._colours(np.array([-5.0, -1.0, 1.0, 3.0, 9.0]), -1.0, 3.0)
    assert colours.shape == (5, 3) and colours.dtype == np.uint8
    np.testing.assert_array_equal(colours[[0, 1]], lut[[0, 0]])          # at and below the low limit
    np.testing.assert_array_equal(colours[[3, 4]], lut[[255, 255]])      # at and above the high limit
    np.testing.assert_array_equal(colours[2], lut[128])                  # halfway
    logger._scale = 2
    shown = logger._display_image(np.full((8, 12), 4095, np.uint16), "Mono12")
    assert shown.dtype == np.uint8 and shown.shape == (4, 6) and shown.max() == 255
    # a 10-bit camera's full scale is 1023: white, not a quarter grey
    assert logger._display_image(np.full((8, 12), 1023, np.uint16), "Mono10").min() == 255


@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_periodic_flush_keeps_scalars_after_a_kill(tmp_path):
    """The stream is flushed about once a second: a SIGKILLed run's .rrd still has its P0 series."""
    path = tmp_path / "killed.rrd"
    code = f"""
import os, signal, sys, time
sys.path.insert(0, {REPO!r}); sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r})
from test_logger_entities import _result
from livedic.stream.view.logger import RerunLogger
from livedic.stream.pipeline.frame_result import SessionStats
logger = RerunLogger("save", {str(path)!r}, flush_interval_s=0.2)
logger.start(image_shape=(96, 128), p0_index=0, points=None)
for i in range(30):
    logger.log_frame(_result(i), SessionStats())
    time.sleep(0.02)
os.kill(os.getpid(), signal.SIGKILL)
"""
    subprocess.run([sys.executable, "-c", code], timeout=120, cwd=str(tmp_path))
    values = _scalars(path, "/p0")
    assert len(values) >= 15
