"""The strain stage with a calibration: a uniform 1 % stretch filmed through a k1 = -0.12 lens reads wrong
near the corners without the correction and right with it (centre and corners, strain field and extensometers)."""

import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens, render_through_lens
from livedic.dic.calibration import CameraCalibration, plane_from_homography
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
    # fronto-parallel at 10 px/mm: board mm x 10 = ideal px, so plane px are ideal px
    fronto = plane_from_homography("simulated", np.diag([10.0, 10.0, 1.0]), np.array([centre, centre]) / 10.0,
                                   lens.camera_matrix)
    truth = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "simulated lens", 1.0,
                              plane=fronto)
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
    assert stage.config.px_per_mm == pytest.approx(10.0, rel=1e-12)
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


TILT_DEG = 8.0


@pytest.fixture(scope="module")
def tilted():
    """The same stretch (along the plane's y, about the image's centre) printed on a specimen plane tilted by
    ``TILT_DEG`` about x, through the lens; the true calibration with the plane's homography."""
    from livedic.acquire.simulator.targets import plane_view, pose_homography, scene_on_plane
    from livedic.dic.calibration import parse_target
    lens = Lens((SIZE, SIZE), k1=-0.12)
    spec = parse_target("chessboard:9x6")
    pose = plane_view(spec, 2.5, lens, 10.0, TILT_DEG)
    H = pose_homography(lens, pose)
    centre_mm = spec.object_points(2.5).mean(axis=0)[:2]
    centre = (SIZE - 1) / 2.0
    pattern = SpecklePattern((SIZE, SIZE), density=1000.0 / 65536.0, radius=3.0, seed=3, margin=40)
    reference = render_through_lens(pattern, lens, scene_on_plane(H, centre_mm, (centre, centre), 10.0))
    deformed = render_through_lens(pattern, lens, scene_on_plane(
        H, centre_mm, (centre, centre), 10.0, lambda X, Y: (X, centre_mm[1] + (Y - centre_mm[1]) / (1.0 + STRETCH))))
    xs, ys = np.meshgrid(np.arange(24.0, SIZE - 24, STEP), np.arange(24.0, SIZE - 24, STEP))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    found = measure(reference, deformed, points, subset=SUBSET, subpixel="icgn", radius=8)
    plane = plane_from_homography("tilted", H, centre_mm, lens.camera_matrix)
    truth = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "simulated lens", 1.0,
                              plane=plane)
    return points, found, truth, lens, H


def test_a_tilted_plane_measured_through_its_homography(tilted):
    """On a plane tilted 8 deg the perspective makes a uniform stretch read non-uniform in ideal px (exx and eyy
    off by ~ tan(tilt) x y / f x strain towards the top and bottom): the plane's homography removes it, and
    the extensometer's L0 in mm is the length on the plane, not foreshortened."""
    from dataclasses import replace
    from livedic.dic.strain.extensometer import Extensometer
    points, found, truth, lens, H = tilted
    assert found.ok.all() and abs(truth.plane.tilt_deg - TILT_DEG) < 1e-9
    axial = (Extensometer("axial", 192.0, 60.0, 192.0, 320.0),)
    lens_only = replace(truth, plane=None)
    rows = {}
    for name, config in (("one px/mm", StrainConfig(window=5, calibration=lens_only, scale=truth.px_per_mm,
                                                    extensometers=axial)),
                         ("homography", StrainConfig(window=5, calibration=truth, extensometers=axial))):
        stage = config.place(points, p0=points[len(points) // 2], roi=(0, 0, SIZE, SIZE), step=STEP, subset=SUBSET,
                             image_size=(SIZE, SIZE))
        strain, readings = stage.compute(found.u, found.v, found.ok)
        far = np.abs(points[:, 1] - (SIZE - 1) / 2.0) > 120          # the top and bottom rows
        rows[name] = (float(np.mean(np.abs(strain.eyy[far] - STRETCH))), float(np.mean(np.abs(strain.exx[far]))),
                      abs(readings.eng_strain[0] - STRETCH), stage.config.in_mm(readings.l0_px[0]))
    ends = lens.undistort(np.array([[192.0, 60.0], [192.0, 320.0]]))
    board = np.linalg.solve(H, np.vstack([ends.T, np.ones(2)]))
    true_l0_mm = float(np.linalg.norm(board[:2, 1] / board[2, 1] - board[:2, 0] / board[2, 0]))
    raw, fixed = rows["one px/mm"], rows["homography"]
    # measured (mean over the top and bottom rows): |eyy - 1 %| 1059 and |exx| 524 microstrain with one px/mm,
    # 18 and 17 through the homography; the axial extensometer (symmetric about the centre) 8.9 and 3.9; its L0
    # 26.503 mm with one px/mm against 26.664 mm on the plane, exact through the homography
    assert raw[0] > 5e-4 and raw[1] > 2.5e-4
    assert fixed[0] < 1e-4 and fixed[1] < 1e-4 and fixed[2] < 2e-5
    assert abs(fixed[3] / true_l0_mm - 1.0) < 1e-6 and abs(raw[3] / true_l0_mm - 1.0) > 2e-3
