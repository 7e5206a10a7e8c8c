"""The live stress-strain curve (issue 13): force against time and stress against axial strain, in Rerun.

Read back from the saved .rrd. The displacement field is linear (uniform strain, e_yy = 0.001 i in frame i,
as in test_logger_strain) and the force a ramp F = 1000 i N on A0 = 10 mm^2, so every logged value is exact:
stress 100 i MPa at axial strain 0.1 i %, true strain ln(1 + 0.001 i), true stress 100 i (1 + 0.001 i).
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from livedic.stream.view import blueprint, entities, xy_plot
from livedic.stream.stages.force import LoadStage, axial_strain
from livedic.stream.view.logger import RerunLogger
from livedic.stream.stages.stress import NECKING_DROP, UniformElongationWatch
from livedic.stream.pipeline.frame_result import SessionStats
from tests.stream.view.test_logger_strain import EYY, FRAMES, ROI, _field, _points, _stage, _views
from tests.stream.view.test_logger import SHAPE, _frame_result, _rows

AREA = 10.0


def _force(i):
    return 1000.0 * i


def _session(path, *, force=_force, fracture_at=None, area=AREA):
    """Log FRAMES frames with the strain stage and a load stage's values; returns the per-frame results."""
    points = _points()
    x, y = points[:, 0], points[:, 1]
    stage = _stage(points)
    load = SimpleNamespace(area_mm2=area)                 # what the view reads of the session's LoadStage
    watch = UniformElongationWatch(area) if area else None
    logger = RerunLogger("save", str(path), image_max_side=max(SHAPE))
    logger.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=points, strain=stage, load=load)
    results = []
    for i in range(FRAMES):
        u, v = _field(i, x, y)
        result = _frame_result(i, x, y, u, v)
        stage.on_frame(result)
        f = force(i)
        result.force_N, result.stress_MPa = f, f / area if area else math.nan
        if watch is not None:
            result.true_strain, result.true_stress_MPa = watch(f, axial_strain(result))
        if fracture_at is not None and i == fracture_at:
            result.fracture = object()
        logger.log_frame(result, SessionStats())
        results.append(result)
    logger.close()
    return results


def test_force_and_the_stress_strain_curves_are_logged_exactly(tmp_path):
    path = tmp_path / "stress.rrd"
    _session(path)
    force = _rows(path, f"/{entities.FORCE}", "Scalars:scalars")
    assert sorted(force) == list(range(FRAMES))
    np.testing.assert_allclose([force[i][0] for i in range(FRAMES)], [_force(i) / 1000 for i in range(FRAMES)])
    # engineering: one segment a frame, in (strain %, -stress MPa) (image coordinates run down)
    curve = _rows(path, f"/{entities.STRESS_STRAIN_CURVE}", "LineStrips2D:strips")
    assert sorted(curve) == list(range(1, FRAMES))
    i = FRAMES - 1
    np.testing.assert_allclose(curve[i][0], [[100 * EYY * (i - 1), -100.0 * (i - 1)], [100 * EYY * i, -100.0 * i]],
                               atol=1e-9)
    # true: ln(1 + e) and F / A0 (1 + e), the force rising all along (uniform elongation throughout)
    true = _rows(path, f"/{entities.STRESS_STRAIN_TRUE}", "LineStrips2D:strips")
    assert sorted(true) == list(range(1, FRAMES))
    e = EYY * i
    np.testing.assert_allclose(true[i][0][1], [100 * math.log1p(e), -100.0 * i * (1 + e)], atol=1e-9)
    now = _rows(path, f"/{entities.STRESS_STRAIN_NOW}", "Points2D:labels")
    assert now[i][0] == f"{100 * e:.3f} %   {100.0 * i:.1f} MPa   F {i:.3f} kN   true {100.0 * i * (1 + e):.1f} MPa"


def test_the_stress_axis_grows_to_cover_the_curve(tmp_path):
    path = tmp_path / "grow.rrd"
    _session(path, force=lambda i: 3_000.0 * i)       # on 10 mm^2: 2,100 MPa at frame 7
    axes = _rows(path, f"/{entities.STRESS_STRAIN}/data", "Transform3D:scale")
    ticks = _rows(path, f"/{entities.STRESS_STRAIN}/ticks", "Points2D:labels")
    last = max(axes)
    width, height = xy_plot._XY_BOX
    # 2,100 MPa -> 2,500 (a nice number: 1, 1.5, 2, 2.5, 3, 4, 5, 6, 8 x 10^k); 0.7 % -> 0.8
    assert axes[last][0] == pytest.approx([width / (0.8 + 0.05), height / 2500.0, 1.0])
    assert "stress (MPa)" in ticks[last] and "axial strain (%)" in ticks[last] and "2500" in ticks[last]


def test_a_frame_without_force_is_a_gap_never_the_last_value(tmp_path):
    path = tmp_path / "gap.rrd"
    _session(path, force=lambda i: math.nan if i == 3 else _force(i))
    force = _rows(path, f"/{entities.FORCE}", "Scalars:scalars")
    assert 3 not in force and all(i in force for i in range(FRAMES) if i != 3)
    cleared = _rows(path, f"/{entities.FORCE}", "Clear:is_recursive")
    assert [i for i, flag in cleared.items() if flag is not None] == [3]
    curve = _rows(path, f"/{entities.STRESS_STRAIN_CURVE}", "LineStrips2D:strips")
    assert sorted(curve) == [1, 2, 5, 6, 7]                    # nothing into or out of frame 3
    now_cleared = _rows(path, f"/{entities.STRESS_STRAIN_NOW}", "Clear:is_recursive")
    assert [i for i, flag in now_cleared.items() if flag is not None] == [3]


def test_the_curve_ends_when_the_broken_specimen_lets_go(tmp_path):
    """After a detected fracture, the first frame below 10 % of the maximum force ends the curve: the
    simulator's broken halves pulled further apart are not a stress-strain curve."""
    path = tmp_path / "broken.rrd"
    _session(path, force=lambda i: 0.0 if i >= 5 else _force(i), fracture_at=5)
    curve = _rows(path, f"/{entities.STRESS_STRAIN_CURVE}", "LineStrips2D:strips")
    assert sorted(curve) == [1, 2, 3, 4, 5]                    # the fall is drawn, then nothing
    now = _rows(path, f"/{entities.STRESS_STRAIN_NOW}", "Points2D:labels")
    assert now[5][0].endswith("broken") and max(now) == 5
    force = _rows(path, f"/{entities.FORCE}", "Scalars:scalars")
    assert sorted(force) == list(range(FRAMES))                # the force itself is still shown
    # a fall in force without a detected fracture (an unloading, a slipping grip) does not end the curve
    path = tmp_path / "unload.rrd"
    _session(path, force=lambda i: 0.0 if i == 5 else _force(i))
    assert sorted(_rows(path, f"/{entities.STRESS_STRAIN_CURVE}", "LineStrips2D:strips")) == list(range(1, FRAMES))


def test_the_plots_are_in_the_blueprint_only_with_what_they_need(tmp_path):
    points = _points()
    stage = _stage(points)
    names = [name for _, name, _ in _views(RerunLogger("save", "unused.rrd")._make_blueprint(
        True, stage, SimpleNamespace(area_mm2=AREA)))]
    assert names.index("stress-strain (MPa, %)") < names.index("extensometer strain (%)") \
        < names.index("force (kN)") < names.index(blueprint._SMALL_PLOT_NAMES[entities.P0])
    # a force without a cross-section: the force, no curve; no axial extensometer: the same
    for load, strain in ((SimpleNamespace(area_mm2=None), stage),
                         (SimpleNamespace(area_mm2=AREA), _stage(points, gauge_length=None, gauge_width=None))):
        names = [name for _, name, _ in _views(RerunLogger("save", "unused.rrd")._make_blueprint(True, strain, load))]
        assert "force (kN)" in names and "stress-strain (MPa, %)" not in names
    path = tmp_path / "no_area.rrd"
    _session(path, area=None)
    assert _rows(path, f"/{entities.FORCE}", "Scalars:scalars")
    assert not _rows(path, f"/{entities.STRESS_STRAIN_CURVE}", "LineStrips2D:strips")


# --------------------------------------------------------------------------- live true values

def test_true_values_stop_for_good_once_the_force_falls_below_its_maximum():
    watch = UniformElongationWatch(AREA)
    strain = 0.01
    assert watch(1000.0, strain) == pytest.approx((math.log1p(strain), 100.0 * (1 + strain)), rel=1e-12)
    # within NECKING_DROP of the maximum: still uniform (a plateau, the load cell's noise)
    assert math.isfinite(watch(1000.0 * (1 - 0.9 * NECKING_DROP), 0.02)[1])
    assert all(math.isnan(v) for v in watch(math.nan, 0.02))           # no force: NaN, the watch unchanged
    assert all(math.isnan(v) for v in watch(1000.0, math.nan))         # no strain: NaN
    assert all(math.isnan(v) for v in watch(1000.0 * (1 - 1.1 * NECKING_DROP), 0.03))   # past Ag
    assert watch.ended
    assert all(math.isnan(v) for v in watch(2000.0, 0.04))             # for good, even if the force rises again


def test_the_load_stage_gives_true_values_from_the_axial_extensometer(tmp_path):
    ramp = tmp_path / "force.csv"
    ramp.write_text("time_s,force_N\n0,0\n1,50000\n")                  # 50 kN/s: 1000 N per 20 ms frame
    from livedic.acquire.force import open_load
    points = _points()
    x, y = points[:, 0], points[:, 1]
    stage = _stage(points)
    with open_load(f"csv:{ramp}") as load:
        force_stage = LoadStage(load, AREA, lambda *event: None)
        for i in range(3):
            result = _frame_result(i, x, y, *_field(i, x, y))
            stage.on_frame(result)
            force_stage.on_frame(result)
    e = EYY * 2
    assert result.force_N == pytest.approx(2000.0) and result.stress_MPa == pytest.approx(200.0)
    assert result.true_strain == pytest.approx(math.log1p(e), abs=1e-9)
    assert result.true_stress_MPa == pytest.approx(200.0 * (1 + e), rel=1e-9)
    without_area = LoadStage(SimpleNamespace(), None, None)
    assert without_area.uniform is None                                 # no A0: no stress, no true values
