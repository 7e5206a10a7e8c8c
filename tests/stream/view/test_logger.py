"""What the live Rerun view shows, read back from the saved .rrd: disc sizes, colour limits, lost points.

Issue 8: the u/v panels showed only the grey image (discs of radius 0.25 px when P0 sat 1 px
from a grid column), the colour map was rescaled to each frame's min/max, the colour-bar labels
were white on light grey, and nothing marked lost or weakly correlated points.
"""

import numpy as np
import pytest

from livedic.acquire.base import Frame
from livedic.dic.result import Measurement
from livedic.stream.view import entities
from livedic.stream.view.colour_scale import colormap_lut
from livedic.stream.view.logger import RerunLogger
from livedic.stream.pipeline.frame_result import FrameResult, SessionStats

SHAPE = (240, 320)


def _grid_with_p0(step=16):
    """A grid over the image with P0 first, 1 px beside a grid point (the default run's layout)."""
    xs, ys = np.meshgrid(np.arange(40.0, 280.0, step), np.arange(40.0, 200.0, step))
    p0 = (xs[0, 5] + 1.0, ys[3, 0])
    return np.concatenate([[p0[0]], xs.ravel()]), np.concatenate([[p0[1]], ys.ravel()])


def _frame_result(i, x, y, u, v, ok=None, zncc=None):
    n = x.size
    ok = np.ones(n, dtype=bool) if ok is None else ok
    zncc = np.full(n, 0.97) if zncc is None else zncc
    m = Measurement(x=x, y=y, u=np.where(ok, u, np.nan), v=np.where(ok, v, np.nan),
                    zncc=np.where(ok, zncc, np.nan), ok=ok, status=np.where(ok, 0, 7).astype(np.int8))
    frame = Frame(i, i * 20_000_000, np.zeros(SHAPE, np.uint8), "Mono8", None)
    return FrameResult(frame=frame, arrival_ns=i * 20_000_000, done_ns=i * 20_000_000 + 2_000_000,
                       processing_ns=1_000_000, measurement=m, is_reference=i == 0, frames_done=i + 1,
                       dropped_total=0, dropped_since_last=0, queue_depth=0, refound=0,
                       error_rms_px=float("nan"), error_max_px=float("nan"))


def _session(path, results, x, y, **options):
    logger = RerunLogger("save", str(path), image_max_side=max(SHAPE), **options)
    logger.start(image_shape=SHAPE, roi=(40, 40, 240, 160), p0_index=0, points=np.column_stack([x, y]))
    for result in results:
        logger.log_frame(result, SessionStats())
    logger.close()
    return logger


def _rows(path, entity, column):
    """{frame: value of ``column``} for the temporal rows of ``entity``; 'static' for a static row."""
    from rerun.chunk import RrdReader
    rows = {}
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if str(chunk.entity_path) != entity:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        values = batch.column(column).to_pylist()
        frames = ["static"] * len(values) if chunk.is_static else batch.column("frame").to_pylist()
        rows.update(zip(frames, values))
    return rows


def _lut_indices(packed_colours):
    """Colour-map index of each logged colour (Rerun packs colours as 0xRRGGBBAA)."""
    lut = colormap_lut().astype(np.int64)
    packed = np.array(packed_colours, dtype=np.int64)
    rgb = np.column_stack([(packed >> 24) & 255, (packed >> 16) & 255, (packed >> 8) & 255])
    return np.abs(rgb[:, None, :] - lut[None, :, :]).sum(axis=2).argmin(axis=1)


# --------------------------------------------------------------------------- disc size

def test_field_discs_cover_a_grid_whose_p0_sits_1_px_from_a_grid_point(tmp_path):
    x, y = _grid_with_p0(step=16)
    path = tmp_path / "grid.rrd"
    _session(path, [_frame_result(i, x, y, 0.1 * i * x / 100, -0.1 * i * y / 100) for i in range(3)], x, y)
    for entity in (f"/{entities.FIELD_U}", f"/{entities.FIELD_V}"):
        radii = _rows(path, entity, "Points2D:radii")
        assert set(radii) == {0, 1, 2}
        # discs of radius step/sqrt(2) leave no gap on a square grid; the old rule gave 0.5 px
        assert all(r[0] == pytest.approx(16 / np.sqrt(2), rel=1e-6) for r in radii.values())
        positions = _rows(path, entity, "Points2D:positions")
        assert len(positions[2]) == x.size


def test_field_discs_cover_an_irregular_point_set(tmp_path):
    rng = np.random.default_rng(3)
    x, y = np.round(rng.uniform(40, 280, 400)), np.round(rng.uniform(40, 200, 400))
    mean_spacing = np.sqrt(240 * 160 / 400)                   # ~9.8 px
    path = tmp_path / "irregular.rrd"
    _session(path, [_frame_result(i, x, y, 0.05 * i + 0 * x, 0 * y) for i in range(2)], x, y)
    radius = _rows(path, f"/{entities.FIELD_U}", "Points2D:radii")[1][0]
    assert 0.4 * mean_spacing <= radius <= mean_spacing


# --------------------------------------------------------------------------- colour scale

def test_automatic_colour_limits_start_small_only_grow_and_are_logged(tmp_path):
    x, y = _grid_with_p0(step=16)
    rng = np.random.default_rng(0)
    amplitudes = [0.0, 0.3, 1.2, 2.6, 0.5, 0.0]              # the test loads, then unloads
    results = []
    for i, a in enumerate(amplitudes):
        u = a * (x - 160) / 120 + 1e-7 * rng.standard_normal(x.size)     # noise only at frame 0
        results.append(_frame_result(i, x, y, u, 0.5 * u))
    path = tmp_path / "limits.rrd"
    logger = _session(path, results, x, y)
    limits = _rows(path, f"/{entities.LIMITS_U}", "Scalars:scalars")
    assert limits[0] == [-0.05, 0.05]
    frames = sorted(limits)
    for before, after in zip(frames, frames[1:]):
        assert limits[after][0] <= limits[before][0] and limits[after][1] >= limits[before][1]
    # u spans -2.6 .. +2.25 px at frame 3: each end moves out to the next nice number
    assert frames[-1] == 3 and limits[3] == [-3.0, 2.5]
    assert logger.colour_limits[entities.LEGEND_U] == (-3.0, 2.5)
    colours = _rows(path, f"/{entities.FIELD_U}", "Points2D:colors")
    noise = _lut_indices(colours[0])                           # +-1e-7 px of noise: one colour, not a rainbow
    assert noise.max() - noise.min() <= 1                      # (0 may sit on the edge of two neighbours)
    spread = _lut_indices(colours[2])                          # a frame that set the scale uses most of it
    assert spread.max() - spread.min() > 150
    # after unloading the scale stays at [-3, 2.5]: +-0.5 px uses the middle of the map, not all of it
    indices = _lut_indices(colours[4])
    assert 110 <= indices.min() and indices.max() <= 165 and indices.max() - indices.min() > 30
    bars = _rows(path, f"/{entities.LEGEND_U}/bar", "Image:buffer")
    assert set(bars) == set(frames)                                 # the labelled bar follows each change


def test_fixed_colour_range_is_static_and_frames_of_different_amplitude_look_different(tmp_path):
    x, y = _grid_with_p0(step=16)
    results = [_frame_result(i, x, y, a * (x - 160) / 120, 0 * y) for i, a in enumerate([0.0, 0.5, 1.5])]
    path = tmp_path / "fixed.rrd"
    _session(path, results, x, y, color_range=(-2, 2))
    assert _rows(path, f"/{entities.LIMITS_U}", "Scalars:scalars") == {"static": [-2.0, 2.0]}
    assert _rows(path, f"/{entities.LIMITS_V}", "Scalars:scalars") == {"static": [-2.0, 2.0]}
    colours = _rows(path, f"/{entities.FIELD_U}", "Points2D:colors")
    assert colours[1] != colours[2]


@pytest.mark.parametrize("bad", [(1.0, -1.0), (0.0, 0.0), (float("nan"), 1.0)])
def test_bad_colour_range_is_refused(bad):
    with pytest.raises(ValueError, match="colour range"):
        RerunLogger("none", color_range=bad)


def test_lost_and_low_zncc_points_are_marked_and_counted(tmp_path):
    x, y = _grid_with_p0(step=16)
    n = x.size
    lost_at_2 = np.zeros(n, dtype=bool)
    lost_at_2[[3, 7, 40]] = True
    zncc = np.full(n, 0.97)
    zncc[[10, 11]] = 0.6
    u = np.full(n, 2.0)
    results = [_frame_result(0, x, y, 0 * u, 0 * u), _frame_result(1, x, y, u, 0 * u),
               _frame_result(2, x, y, u + 1, 0 * u, ok=~lost_at_2, zncc=zncc),
               _frame_result(3, x, y, u + 2, 0 * u)]
    path = tmp_path / "lost.rrd"
    _session(path, results, x, y)
    centers = _rows(path, f"/{entities.LOST}", "Boxes2D:centers")
    assert list(centers) == [2]
    # the lost points are marked where they were last seen (frame 1: u = 2)
    np.testing.assert_allclose(sorted(c[0] for c in centers[2]), sorted(x[lost_at_2] + 2.0))
    np.testing.assert_allclose(sorted(c[1] for c in centers[2]), sorted(y[lost_at_2]))
    assert len(_rows(path, f"/{entities.LOW_ZNCC}", "Boxes2D:centers")[2]) == 2
    # the markers are cleared when the points are back
    assert 3 in _rows(path, f"/{entities.LOST}", "Clear:is_recursive")
    texts = _rows(path, f"/{entities.TRACKING}", "TextDocument:text")
    assert texts[0] == [f"lost: 0 of {n} points, low ZNCC (< 0.8): 0"]
    assert texts[2] == [f"lost: 3 of {n} points, low ZNCC (< 0.8): 2"]
    assert texts[3] == texts[0]


# --------------------------------------------------------------------------- through livedic run

def test_run_passes_color_range_and_refind_zncc_to_the_view(tmp_path, monkeypatch):
    """``--color-range -2,2`` (a value starting with a minus sign, as typed) fixes both colour scales;
    the low-ZNCC markers use ``--refind-zncc``."""
    from livedic.stream.cli import main
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)
    path = tmp_path / "view.rrd"
    assert main(["run", "--source", "synthetic:translate?size=128x128&pace=0", "--frames", "5", "--progress", "off",
                 "--no-record", "--viewer", "save", str(path), "--color-range", "-2,2",
                 "--refind-zncc", "0.95", "--static-frames", "0"]) == 0
    assert _rows(path, f"/{entities.LIMITS_U}", "Scalars:scalars") == {"static": [-2.0, 2.0]}
    assert _rows(path, f"/{entities.LIMITS_V}", "Scalars:scalars") == {"static": [-2.0, 2.0]}
    assert len(_rows(path, f"/{entities.FIELD_U}", "Points2D:positions")) == 5
    texts = _rows(path, f"/{entities.TRACKING}", "TextDocument:text")
    assert texts and all("low ZNCC (< 0.95)" in text[0] for text in texts.values())


def test_run_without_color_range_uses_the_automatic_scale(tmp_path, monkeypatch):
    from livedic.stream.cli import main
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)
    path = tmp_path / "auto.rrd"
    assert main(["run", "--source", "synthetic:translate?size=128x128&pace=0", "--frames", "3", "--progress", "off",
                 "--no-record", "--viewer", "save", str(path)]) == 0
    limits = _rows(path, f"/{entities.LIMITS_U}", "Scalars:scalars")
    assert "static" not in limits and limits[0] == [-0.05, 0.05]
    assert _rows(path, f"/{entities.TRACKING}", "TextDocument:text")[0][0].endswith("low ZNCC (< 0.8): 0")
