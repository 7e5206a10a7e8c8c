"""The strain stage with a calibration: a uniform 1 % stretch filmed through a k1 = -0.12 lens reads wrong
near the corners without the correction and right with it (centre and corners, strain field and extensometers)."""

import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens, render_through_lens
from livedic.dic.calibration import CameraCalibration, PlaneScale
from livedic.dic.measure import measure
from livedic.dic.speckle import SpecklePattern
from livedic.stream.stages.strain import StrainConfig

SIZE = 384
STRETCH = 0.01          # engineering strain along y, about the image centre, none along x
SUBSET, STEP = 25, 12


@pytest.fixture(scope="module")
def stretched():
    lens = Lens((SIZE, SIZE), k1=-0.12)
    pattern = SpecklePattern((SIZE, SIZE), density=1000.0 / 65536.0, radius=3.0, seed=3, margin=40)
    centre = (SIZE - 1) / 2.0
    reference = render_through_lens(pattern, lens, lambda x, y: (x, y))
    deformed = render_through_lens(pattern, lens, lambda x, y: (x, centre + (y - centre) / (1.0 + STRETCH)))
    xs, ys = np.meshgrid(np.arange(24.0, SIZE - 24, STEP), np.arange(24.0, SIZE - 24, STEP))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    found = measure(reference, deformed, points, subset=SUBSET, subpixel="icgn", radius=8)
    truth = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "simulated lens", 1.0,
                              plane=PlaneScale("simulated", 10.0, (10.0, 10.0), 0.0, np.eye(3), 0.0))
    return points, found, truth


def _errors(points, found, calibration, extensometers=()):
    config = StrainConfig(window=5, calibration=calibration, extensometers=extensometers)
    stage = config.place(points, p0=points[len(points) // 2], roi=(0, 0, SIZE, SIZE), step=STEP, subset=SUBSET,
                         image_size=(SIZE, SIZE))
    strain, readings = stage.compute(found.u, found.v, found.ok)
    r = np.hypot(points[:, 0] - (SIZE - 1) / 2.0, points[:, 1] - (SIZE - 1) / 2.0)
    error = np.abs(strain.eyy - STRETCH) + np.abs(strain.exx)
    ok = strain.ok
    return (float(np.nanmax(error[ok & (r < 60)])), float(np.nanmax(error[ok & (r > 200)])),
            np.abs(readings.eng_strain - STRETCH), stage)


def test_the_correction_removes_the_lens_error_near_the_corners(stretched):
    points, found, truth = stretched
    assert found.ok.all()
    from livedic.dic.strain.extensometer import Extensometer
    corner = (Extensometer("corner", 40.0, 40.0, 40.0, 200.0),)
    centre_raw, corner_raw, ext_raw, _ = _errors(points, found, None, corner)
    centre_cal, corner_cal, ext_cal, stage = _errors(points, found, truth, corner)
    # Without the correction (measured, |eyy - 1 %| + |exx| at worst): 270 microstrain within 60 px of the
    # centre, 1980 beyond 200 px, 409 on the extensometer along the left edge.
    assert corner_raw > 1e-3 and corner_raw > 4 * centre_raw and ext_raw[0] > 2e-4
    # With it (measured): 56 and 80 microstrain, 6 on the extensometer: the noise of the plane fits is left.
    assert centre_cal < 1.2e-4 and corner_cal < 1.2e-4 and ext_cal[0] < 2e-5
    assert stage.config.px_per_mm == 10.0
    # the recorded ends are image positions: placed again from them, they are the same ideal ends
    again = StrainConfig.from_metadata({**stage.config.as_metadata(), **stage.metadata()})
    replaced = again.place(points, p0=points[len(points) // 2], roi=(0, 0, SIZE, SIZE), step=STEP, subset=SUBSET)
    np.testing.assert_allclose(replaced.placed.ends, stage.placed.ends, atol=1e-9)


def test_a_calibration_of_another_size_and_two_scales_are_refused(stretched):
    points, _, truth = stretched
    with pytest.raises(ValueError, match="made for 384x384"):
        StrainConfig(calibration=truth).place(points, p0=points[0], roi=(0, 0, SIZE, SIZE), step=STEP, subset=SUBSET,
                                              image_size=(640, 480))
    with pytest.raises(ValueError, match="give one of them"):
        StrainConfig(scale=12.0, calibration=truth)


def test_replay_rows_give_the_undistorted_displacement_in_mm(stretched):
    """``livedic replay``'s rows with a calibration: ``u_mm, v_mm`` are the displacements in ideal px (the lens
    removed) over the plane's px/mm: the stretch's exact motion about the centre, (y_ideal - c) x 1 %, / 10."""
    from livedic.stream.replay.rows import frame_rows
    points, found, truth = stretched
    *_, stage = _errors(points, found, truth)
    strain, _ = stage.compute(found.u, found.v, found.ok)
    rows = frame_rows(3, 0, np.arange(len(points)), found, strain, stage)
    assert rows.header[-2:] == ["u_mm", "v_mm"]
    ideal = stage.ideal_points
    centre = (SIZE - 1) / 2.0
    # measured: 4.8e-4 mm (0.005 px) at worst, where the image's v / 10 is 0.018 mm off
    np.testing.assert_allclose(rows.columns["v_mm"], (ideal[:, 1] - centre) * STRETCH / 10.0, atol=1e-3)
    np.testing.assert_allclose(rows.columns["u_mm"], 0.0, atol=1e-3)
    assert np.max(np.abs(found.v / 10.0 - rows.columns["v_mm"])) > 2e-3
    without = frame_rows(3, 0, np.arange(len(points)), found, strain, None)
    assert "u_mm" not in without.header
