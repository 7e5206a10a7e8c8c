"""The live view of strain (issue 11): e_yy on the image, the extensometers, their strain and transverse vs axial.

Read back from the saved .rrd. The displacement field is linear (uniform strain), so the strain field and
the extensometers are exact: e_yy = 0.001 i and e_xx = -0.0004 i in frame i (Poisson's ratio 0.4).
"""

import numpy as np
import pytest

from livedic.stream.view import blueprint, camera_image, colour_scale, entities
from livedic.stream.stages.contraction import ContractionWatch
from livedic.stream.view.colour_scale import nice_ceil
from livedic.stream.view.logger import RerunLogger
from livedic.stream.stages.strain import StrainConfig
from livedic.stream.pipeline.frame_result import SessionStats
from tests.stream.view.test_logger import SHAPE, _frame_result, _lut_indices, _rows

STEP = 16
ROI = (32, 24, 256, 192)
P0 = (160.0, 120.0)
EYY, EXX = 0.001, -0.0004          # strain per frame
FRAMES = 8
GREY = int(colour_scale.pack_colours([entities.NO_STRAIN_COLOUR])[0])
RED = int(colour_scale.pack_colours([entities.EXTENSOMETER_LOST_COLOUR])[0])


def _points():
    """P0 first, then the grid (without P0's duplicate), as a session orders them."""
    xs, ys = np.meshgrid(np.arange(32.0, 289.0, STEP), np.arange(24.0, 217.0, STEP))
    grid = np.column_stack([xs.ravel(), ys.ravel()])
    grid = grid[~np.all(grid == P0, axis=1)]
    return np.vstack([[P0], grid])


def _stage(points, **config):
    config = {"gauge_length": 128, "gauge_width": 128, **config}
    return StrainConfig(**config).place(points, p0=points[0], roi=ROI, step=STEP, subset=21)


def _field(i, x, y):
    return EXX * i * (x - P0[0]), EYY * i * (y - P0[1])


def _isolate_top_end(stage, x, y):
    """ok mask that loses every point around the axial extensometer's top end but the one nearest to it
    (that one keeps its displacement and loses its strain: its window is almost empty)."""
    top = stage.placed.ends[0]
    distance = np.hypot(x - top[0], y - top[1])
    ok = distance > 2.6 * STEP
    ok[np.argmin(distance)] = True
    return ok


def _session(path, *, strain=True, lose=(), stage_config=None, feed_strain=True):
    """Log FRAMES frames; ``lose``: frames where the axial's top end is lost. Returns (logger, stage, readings)."""
    points = _points()
    x, y = points[:, 0], points[:, 1]
    stage = _stage(points, **(stage_config or {}))
    logger = RerunLogger("save", str(path), image_max_side=max(SHAPE))
    options = {"strain": stage} if strain else {}
    logger.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=points, **options)
    readings = []
    watch = ContractionWatch(refit_interval_s=0.0)      # refitted every frame: the view shows the last frame's fit
    for i in range(FRAMES):
        u, v = _field(i, x, y)
        ok = _isolate_top_end(stage, x, y) if i in lose else None
        result = _frame_result(i, x, y, u, v, ok=ok)
        if feed_strain:
            stage.on_frame(result)
            watch(result, SessionStats())
            readings.append(result.extensometers)
        logger.log_frame(result, SessionStats())
    logger.close()
    return logger, stage, readings


def _views(blueprint):
    """(kind, name, origin) of every view of a blueprint, in layout order."""
    from rerun.blueprint.api import Container

    def walk(item):
        if isinstance(item, Container):
            for child in item.contents:
                yield from walk(child)
        else:
            yield type(item).__name__, str(item.name), str(item.origin)
    return list(walk(blueprint.root_container))


# --------------------------------------------------------------------------- what is logged

def test_strain_view_logs_eyy_extensometers_and_the_transverse_vs_axial_plot(tmp_path):
    path = tmp_path / "strain.rrd"
    _session(path)
    axial = _rows(path, f"/{entities.EXTENSOMETER_STRAIN}/axial", "Scalars:scalars")
    transverse = _rows(path, f"/{entities.EXTENSOMETER_STRAIN}/transverse", "Scalars:scalars")
    assert sorted(axial) == list(range(FRAMES)) == sorted(transverse)
    # engineering strain in %, exact on a linear field (the ends' quadratic fits reproduce it)
    np.testing.assert_allclose([axial[i][0] for i in range(FRAMES)], [100 * EYY * i for i in range(FRAMES)],
                               atol=1e-9)
    np.testing.assert_allclose([transverse[i][0] for i in range(FRAMES)], [100 * EXX * i for i in range(FRAMES)],
                               atol=1e-9)
    # e_yy's scale starts at +-0.1 % and grows to round numbers covering the field: 0.007 -> 0.008
    limits = _rows(path, f"/{entities.LIMITS_EYY}", "Scalars:scalars")
    assert limits[0] == [-colour_scale.MIN_COLOUR_LIMIT_STRAIN, colour_scale.MIN_COLOUR_LIMIT_STRAIN]
    assert limits[max(limits)] == [-0.001, nice_ceil(EYY * (FRAMES - 1))] == [-0.001, 0.008]
    assert all(hi == nice_ceil(hi) for _, hi in limits.values())
    bars = _rows(path, f"/{entities.LEGEND_EYY}/bar", "Image:buffer")
    assert sorted(bars) == sorted(limits)                      # a new bar whenever the limits change
    # every point coloured by its e_yy on that scale: 0.007 on [-0.001, 0.008] is index 227 of 256
    colours = _rows(path, f"/{entities.FIELD_EYY}", "Points2D:colors")
    last = np.array(colours[FRAMES - 1], dtype=np.int64)
    assert last.size == len(_points())
    assert set(_lut_indices(last)) == {round(255 * (0.007 + 0.001) / 0.009)}
    # the extensometers on the image at their ends' current positions, labelled with their strain
    strips = _rows(path, f"/{entities.EXTENSOMETER_LINES}", "LineStrips2D:strips")[FRAMES - 1]
    labels = _rows(path, f"/{entities.EXTENSOMETER_LINES}", "LineStrips2D:labels")[FRAMES - 1]
    assert labels == ["axial 0.700 %", "transverse -0.280 %"]
    e = EYY * (FRAMES - 1)
    axial_line = np.array(strips[-2])                           # the coloured lines come last
    np.testing.assert_allclose(axial_line, [[160, 56 + e * (56 - 120)], [160, 184 + e * (184 - 120)]], atol=1e-4)
    # transverse vs axial: one segment a frame from the second frame on, the numbers with Poisson's ratio
    curve = _rows(path, f"/{entities.STRAIN_XY_CURVE}", "LineStrips2D:strips")
    assert sorted(curve) == list(range(1, FRAMES))
    np.testing.assert_allclose(curve[FRAMES - 1][0], [[100 * EYY * (FRAMES - 2), -100 * EXX * (FRAMES - 2)],
                                                      [100 * EYY * (FRAMES - 1), -100 * EXX * (FRAMES - 1)]], atol=1e-9)
    # Poisson's ratio: the elastic fit over every frame so far (the field is linear), from the 5th frame on,
    # drawn as a line over its axial range
    now = _rows(path, f"/{entities.STRAIN_XY_NOW}", "Points2D:labels")
    assert f"Poisson 0.400 +- 0.000 (elastic fit, frames 0-{FRAMES - 1})" in now[FRAMES - 1][0]
    assert "Poisson: n/a (too few frames" in now[3][0] and "0.400" not in now[3][0]
    fit = _rows(path, f"/{entities.STRAIN_XY_FIT}", "LineStrips2D:strips")
    assert sorted(fit) == list(range(4, FRAMES))                 # redrawn as the range grows
    np.testing.assert_allclose(fit[FRAMES - 1][0], [[0.0, 0.0], [100 * EYY * (FRAMES - 1), -100 * EXX * (FRAMES - 1)]],
                               atol=1e-9)


def test_strain_view_is_in_the_blueprint_next_to_u_and_v_and_the_plots():
    logger = RerunLogger("save", "unused.rrd")
    points = _points()
    stage = _stage(points)
    logger._xy_pair = blueprint.axial_transverse_pair(stage)
    views = _views(logger._make_blueprint(True, stage))
    names = [name for _, name, _ in views]
    assert names[:2] == ["camera", "tracking"] and f"e_yy (%) engineering, VSG {stage.vsg_px:g} px" in names
    assert names.index("e_yy colour scale (%)") < names.index("u (px)")          # top row: camera and e_yy
    assert names.index("extensometer strain (%)") < names.index("transverse vs axial strain (%)") \
        < names.index(blueprint._SMALL_PLOT_NAMES[entities.P0])
    # a strain field without extensometers: e_yy, no extensometer plots
    views = _views(logger._make_blueprint(True, _stage(points, gauge_length=None, gauge_width=None)))
    names = [name for _, name, _ in views]
    assert "e_yy colour scale (%)" in names and "extensometer strain (%)" not in names


# --------------------------------------------------------------------------- missing values

def test_a_lost_extensometer_is_red_and_its_strain_is_not_logged(tmp_path):
    path = tmp_path / "lost.rrd"
    lose = (3, 4)
    _, _, readings = _session(path, lose=lose)
    assert not readings[3].ok[0] and np.isnan(readings[3].eng_strain[0])     # the stage says lost
    axial = _rows(path, f"/{entities.EXTENSOMETER_STRAIN}/axial", "Scalars:scalars")
    transverse = _rows(path, f"/{entities.EXTENSOMETER_STRAIN}/transverse", "Scalars:scalars")
    assert all(axial.get(i) is None for i in lose)              # no value, neither NaN nor the last one
    assert all(axial[i] is not None for i in range(FRAMES) if i not in lose)
    assert all(transverse[i] is not None for i in range(FRAMES))
    cleared = _rows(path, f"/{entities.EXTENSOMETER_STRAIN}/axial", "Clear:is_recursive")
    assert [i for i, flag in cleared.items() if flag is not None] == [3]       # one gap in the line, at once
    # on the image: red, labelled lost, where its ends were last seen
    labels = _rows(path, f"/{entities.EXTENSOMETER_LINES}", "LineStrips2D:labels")
    colours = _rows(path, f"/{entities.EXTENSOMETER_LINES}", "LineStrips2D:colors")
    strips = _rows(path, f"/{entities.EXTENSOMETER_LINES}", "LineStrips2D:strips")
    assert labels[3][0] == "axial: lost" and labels[5][0].startswith("axial 0.500")
    assert colours[3][-2] == RED and colours[2][-2] != RED and colours[5][-2] != RED
    # the lost (top) end stays where it was last seen, the other follows its material point
    np.testing.assert_allclose(strips[4][-2][0], strips[2][-2][0], atol=1e-4)
    np.testing.assert_allclose(strips[4][-2][1], [160, 184 + 4 * EYY * (184 - 120)], atol=1e-4)
    # the isolated point keeps its disc in the e_yy view, grey: it has a displacement but no strain
    eyy_colours = _rows(path, f"/{entities.FIELD_EYY}", "Points2D:colors")
    assert GREY in eyy_colours[3] and GREY not in eyy_colours[2]
    # transverse vs axial: no segment into or out of the gap, the numbers cleared while it lasts
    curve = _rows(path, f"/{entities.STRAIN_XY_CURVE}", "LineStrips2D:strips")
    assert sorted(curve) == [1, 2, 6, 7]
    now_cleared = _rows(path, f"/{entities.STRAIN_XY_NOW}", "Clear:is_recursive")
    assert [i for i, flag in now_cleared.items() if flag is not None] == [3]


# --------------------------------------------------------------------------- without strain

STRAIN_ENTITIES = ("/camera/field_eyy", "/camera/extensometers", "/legend/eyy", "/colour_scale/eyy",
                   "/extensometers", "/strain_xy")


def _entities(path):
    from rerun.chunk import RrdReader
    return {str(chunk.entity_path) for chunk in RrdReader(str(path)).stream().to_chunks()}


@pytest.mark.parametrize("feed_strain", [True, False])
def test_without_strain_the_view_is_unchanged(tmp_path, feed_strain):
    """No stage given to start(): nothing of strain is logged, even when the results carry it."""
    path = tmp_path / "plain.rrd"
    _session(path, strain=False, feed_strain=feed_strain)
    logged = _entities(path)
    assert not [e for e in logged if e.startswith(STRAIN_ENTITIES)]
    assert {f"/{entities.FIELD_U}", f"/{entities.FIELD_V}", f"/{entities.LEGEND_U}/bar"} <= logged
    views = _views(RerunLogger("save", "unused.rrd")._make_blueprint(True))
    small = [blueprint._SMALL_PLOT_NAMES[path] for path in (entities.P0, entities.QUALITY, entities.THROUGHPUT,
                                                           entities.LATENCY, entities.DROPS, entities.ERROR)]
    assert [name for _, name, _ in views] == [
        "camera", "u (px)", "v (px)", "tracking", "session", "u colour scale (px)", "v colour scale (px)",
        *small, "events"]


def test_a_stage_without_extensometers_shows_only_the_field(tmp_path):
    path = tmp_path / "field.rrd"
    _, _, readings = _session(path, stage_config={"gauge_length": None, "gauge_width": None})
    assert len(readings[0].names) == 0
    logged = _entities(path)
    assert f"/{entities.FIELD_EYY}" in logged
    assert not [e for e in logged if e.startswith(("/camera/extensometers", "/extensometers", "/strain_xy"))]


def test_a_live_view_behind_leaves_out_the_image_never_fields_or_plots(tmp_path):
    """With ``thin_when_behind`` (live sessions) the camera image is left out while results wait for the
    output thread, at most IMAGE_SKIP_MAX frames in a row; every frame's fields, P0's plot and the
    extensometers' series are drawn. Without it (files, replays) every frame's image is drawn too."""
    import dataclasses
    points = _points()
    x, y = points[:, 0], points[:, 1]
    for thin, path in ((True, tmp_path / "thin.rrd"), (False, tmp_path / "all.rrd")):
        stage = _stage(points)
        logger = RerunLogger("save", str(path), image_max_side=max(SHAPE), thin_when_behind=thin)
        logger.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=points, strain=stage)
        frames = 12
        for i in range(frames):
            u, v = _field(i, x, y)
            result = dataclasses.replace(_frame_result(i, x, y, u, v), output_backlog=2)   # always behind
            stage.on_frame(result)
            logger.log_frame(result, SessionStats())
        logger.close()
        fields = sorted(_rows(path, f"/{entities.FIELD_U}", "Points2D:positions"))
        images = sorted(_rows(path, f"/{entities.CAMERA_IMAGE}", "Image:buffer"))
        assert fields == list(range(frames))
        assert len(_rows(path, f"/{entities.P0}", "Scalars:scalars")) == frames
        assert len(_rows(path, f"/{entities.EXTENSOMETER_STRAIN}/axial", "Scalars:scalars")) == frames
        if thin:
            gap = camera_image.IMAGE_SKIP_MAX + 1
            assert images == list(range(0, frames, gap)) or images == list(range(gap - 1, frames, gap))
            assert logger.images.images_left_out == frames - len(images)
        else:
            assert images == list(range(frames)) and logger.images.images_left_out == 0


def test_a_live_view_draws_the_camera_image_at_most_its_rate_and_every_frame_s_fields(tmp_path):
    """Frames every 20 ms, ``image_max_hz=20``: the camera image every 50 ms of the frames' clock (frames 0, 3,
    6, ...: 40 ms is too soon, 60 ms is not), the fields and the plots every frame, the rest counted."""
    points = _points()
    x, y = points[:, 0], points[:, 1]
    path = tmp_path / "rate.rrd"
    stage = _stage(points)
    logger = RerunLogger("save", str(path), image_max_side=max(SHAPE), image_max_hz=20.0)
    logger.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=points, strain=stage)
    frames = 10
    for i in range(frames):
        u, v = _field(i, x, y)
        result = _frame_result(i, x, y, u, v)
        stage.on_frame(result)
        logger.log_frame(result, SessionStats())
    logger.close()
    images = sorted(_rows(path, f"/{entities.CAMERA_IMAGE}", "Image:buffer"))
    assert images == [0, 3, 6, 9] and logger.images.images_above_rate == frames - 4 and logger.images.images_left_out == 0
    assert sorted(_rows(path, f"/{entities.FIELD_U}", "Points2D:positions")) == list(range(frames))
    assert sorted(_rows(path, f"/{entities.EXTENSOMETER_STRAIN}/axial", "Scalars:scalars")) == list(range(frames))
    assert sorted(_rows(path, f"/{entities.P0}", "Scalars:scalars")) == list(range(frames))
