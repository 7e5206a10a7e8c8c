"""Tests of stream/stages/stereo_strain.py: the stereo strain stage reads the 3D points of each result (strain on
the surface, extensometers in space), placed with the rig's nominal scale."""

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.dic.stereo import SURFACE_MEASURE, StereoStatus
from livedic.stream.stages.stereo_strain import StereoStrainStage, nominal_px_per_mm, stereo_strain_config
from livedic.stream.stages.strain import StrainConfig


def _points(xyz):
    ok = np.all(np.isfinite(xyz), axis=1)
    return SimpleNamespace(xyz=xyz, ok=ok, status=np.where(ok, StereoStatus.OK, StereoStatus.LEFT_NOT_OK))


def test_a_stretch_in_space_is_read_on_the_surface_and_by_the_extensometers():
    rig = StereoRig.symmetric(Lens((512, 512), focal_px=3000.0), Lens((512, 512), focal_px=3000.0),
                              distance_mm=300.0, angle_deg=20.0)
    calibration = rig.calibration()
    assert nominal_px_per_mm(calibration) == pytest.approx(3000.0 / 300.0, rel=0.01)
    config = stereo_strain_config(StrainConfig(gauge_length=20.0), calibration)
    assert config.measure == SURFACE_MEASURE and config.calibration is None and config.px_per_mm == pytest.approx(10.0,
                                                                                                                 rel=0.01)
    xs, ys = np.meshgrid(np.arange(100.0, 413.0, 12.0), np.arange(40.0, 473.0, 12.0))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    stage = StereoStrainStage.of(config.place(points, p0=np.array([256.0, 256.0]), roi=(100, 40, 312, 432), step=12,
                                              subset=21))
    # the points on a plane tilted 20 degrees about x, 0.1 mm a px, then stretched 1 % along its own y
    tilt = cv2.Rodrigues(np.array([np.radians(20.0), 0.0, 0.0]))[0]
    reference = np.column_stack([0.1 * (points - 256.0), np.zeros(len(points))]) @ tilt.T + [0.0, 0.0, 300.0]
    stretched = reference + 0.01 * ((reference - reference.mean(axis=0)) @ tilt[:, 1])[:, None] * tilt[:, 1]
    results = [SimpleNamespace(fracture=None, measurement=SimpleNamespace(points=_points(xyz)), strain=None,
                               extensometers=None) for xyz in (reference, stretched)]
    for result in results:
        stage.on_frame(result)
    readings = results[1].extensometers
    axial = readings.names.index("axial")
    assert readings.eng_strain[axial] == pytest.approx(0.01, abs=1e-9)
    assert readings.l0_mm[axial] == pytest.approx(20.0, rel=0.02)        # placed at ~10 px/mm: 200 px x 0.1 mm
    inside = results[1].strain.ok
    assert np.mean(inside) > 0.9
    np.testing.assert_allclose(results[1].strain.eyy[inside], 0.5 * (1.01 ** 2 - 1.0), atol=1e-9)
    summary = stage.summary()
    assert summary["in_space"] and summary["extensometers"]["axial"]["L0_mm"] == pytest.approx(readings.l0_mm[axial])
