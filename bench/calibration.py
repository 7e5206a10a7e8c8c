"""``livedic bench calibration``: a calibration recovered from simulated target images against the lens they
were rendered through, and the strain error of a uniform stretch filmed through that lens with and without
the correction, near the image's centre and near its corners.

The truth is the simulator's (``acquire.simulator.lens``): a pinhole camera with f = the image width and
the distortion asked for; targets (``acquire.simulator.targets``) at 9 tilted poses and one fronto-parallel
pose on the specimen plane at ``SCALE_PX_PER_MM``; a speckle stretched 1 % along y (engineering, about the
image centre) rendered exactly through the lens. Strain: livedic's strain stage (window 5) on IC-GN
displacements of a grid, uncorrected, corrected with the recovered calibration, and with the true lens.

Then the specimen plane tilted by ``PLANE_TILT_DEG`` about the image's x (one pose for the plane target and
the speckle printed on the plane, ``acquire.simulator.targets.plane_view``): the same stretch, on the plane,
measured with the recovered lens and one px/mm (ideal px, the foreshortening and perspective left) and with
the plane's homography (plane px); and the error of the centre extensometer's L0 in mm against the truth.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from livedic.acquire.simulator.lens import Lens, render_through_lens
from livedic.acquire.simulator.targets import (calibration_views, plane_view, pose_homography, render_target,
                                               scene_on_plane)
from livedic.dic.calibration import (CameraCalibration, Detection, calibrate, detect_target, parse_target,
                                     plane_from_homography, plane_scale)
from livedic.dic.measure import measure
from livedic.dic.speckle import SpecklePattern
from livedic.dic.strain.extensometer import Extensometer
from livedic.stream.stages.strain import StrainConfig

TARGET = "chessboard:9x6"
SCALE_PX_PER_MM = 10.0
STRETCH = 0.01
PLANE_TILT_DEG = 8.0               # the tilted specimen plane's angle from fronto-parallel (about the image's x)
SUBSET, STEP, WINDOW = 25, 16, 5
CENTRE_FRACTION, CORNER_FRACTION = 0.15, 0.40     # radius (x the image width) inside which "centre", beyond "corner"
FAR_FRACTION = 0.30                # |y - centre| (x the image width) beyond which a point is "top/bottom"


def run_calibration_benchmark(*, size: int = 1024, k1: float = -0.12, k2: float = 0.0, p1: float = 0.0,
                              p2: float = 0.0, views: str | None = None,
                              say: Callable[[str], object] = print) -> dict:
    """Run the benchmark, print its tables with ``say``; returns the numbers (a dict).

    ``views``: a folder to write the target images into (view_NN.png, plane.png), for ``livedic calibrate``.
    """
    lens = Lens((size, size), k1, k2, p1, p2)
    spec = parse_target(TARGET)
    square = _square_mm(spec, size)
    images = [(f"view_{i:02d}.png", render_target(spec, square, lens, pose, seed=i))
              for i, pose in enumerate(calibration_views(spec, square, lens))]
    plane_pose = plane_view(spec, square, lens, SCALE_PX_PER_MM)
    plane_image = render_target(spec, square, lens, plane_pose, seed=999)
    if views is not None:
        os.makedirs(views, exist_ok=True)
        for name, image in images + [("plane.png", plane_image)]:
            cv2.imwrite(os.path.join(views, name), image)
        say(f"wrote {len(images)} views and plane.png to {views}: livedic calibrate {views}/view_*.png --target "
            f"{TARGET} --square {square:g} --plane {views}/plane.png -o CAL.json")
    found = [(name, d) for name, d in ((n, detect_target(i, spec, square)) for n, i in images)
             if isinstance(d, Detection)]
    calibration = calibrate(found, lens.size, target=spec.text, square_mm=square)
    plane = detect_target(plane_image, spec, square)
    assert isinstance(plane, Detection), "the simulated plane target must be found"
    recovered = CameraCalibration(**{**calibration.__dict__, "plane": plane_scale(calibration, "plane.png", plane)})
    numbers = {"size": size, "views": len(found), "parameters": _parameters(lens, recovered)}
    say(f"calibration from {len(found)} views of {TARGET} (square {square:g} mm) of {size}x{size} images, "
        f"reprojection RMS {recovered.rms_px:.3f} px")
    say(f"{'parameter':<12}{'truth':>12}{'recovered':>12}{'error':>12}")
    for name, (truth, value) in numbers["parameters"].items():
        say(f"{name:<12}{truth:>12.5g}{value:>12.5g}{value - truth:>12.3g}")
    centre_mm = spec.object_points(square).mean(axis=0)[:2]
    fronto = pose_homography(lens, plane_pose)
    truth_calibration = CameraCalibration(lens.size, lens.camera_matrix, lens.dist_coeffs, 0.0, (), "the lens", 1.0,
                                          plane=plane_from_homography("truth", fronto, centre_mm, lens.camera_matrix))
    plane = _Plane(fronto, centre_mm)
    numbers["strain"] = _strain_errors(lens, plane, {"uncorrected": {}, "recovered calibration": {"calibration": recovered},
                                                     "true lens": {"calibration": truth_calibration}})
    say(f"uniform {100 * STRETCH:g} % stretch along y through the lens (k1 {k1:g}), errors in microstrain: the mean "
        f"of eyy - {STRETCH:g} and of exx over the points at the centre (r < {CENTRE_FRACTION:g} W) and the corners "
        f"(r > {CORNER_FRACTION:g} W), the largest |eyy - {STRETCH:g}| there, and two extensometers of "
        f"{0.4 * size:.0f} px along y, near the left edge and through the centre")
    say(f"{'correction':<24}{'eyy ctr':>9}{'exx ctr':>9}{'eyy crn':>9}{'exx crn':>9}{'max ctr':>9}{'max crn':>9}"
        f"{'ext edge':>10}{'ext ctr':>9}")
    for name, row in numbers["strain"].items():
        say(f"{name:<24}" + "".join(f"{row[key]:>9.0f}" for key in ("eyy_centre", "exx_centre", "eyy_corners",
                                                                    "exx_corners", "max_centre", "max_corners"))
            + f"{row['edge']:>10.0f}{row['middle']:>9.0f}")
    numbers["tilted"] = _tilted_plane(lens, spec, square, calibration, say)
    return numbers


@dataclass(frozen=True)
class _Plane:
    """The specimen plane the speckle is printed on: board mm -> ideal px, and the board point at the image's
    centre (where the pattern's centre is)."""
    homography: np.ndarray
    centre_mm: np.ndarray


def _tilted_plane(lens: Lens, spec, square: float, calibration: CameraCalibration,
                  say: Callable[[str], object]) -> dict[str, dict[str, float]]:
    """The stretch on a plane tilted by ``PLANE_TILT_DEG``, with one px/mm and with the plane's homography (both
    from the recovered lens and the tilted plane target)."""
    pose = plane_view(spec, square, lens, SCALE_PX_PER_MM, PLANE_TILT_DEG)
    detection = detect_target(render_target(spec, square, lens, pose, seed=998), spec, square)
    assert isinstance(detection, Detection), "the simulated tilted plane target must be found"
    measured = plane_scale(calibration, "tilted plane", detection)
    lens_only = CameraCalibration(**{**calibration.__dict__, "plane": None})
    with_plane = CameraCalibration(**{**calibration.__dict__, "plane": measured})
    plane = _Plane(pose_homography(lens, pose), spec.object_points(square).mean(axis=0)[:2])
    errors = _strain_errors(lens, plane, {"one px/mm": {"calibration": lens_only, "scale": measured.px_per_mm},
                                          "plane homography": {"calibration": with_plane}})
    say(f"the specimen plane tilted {PLANE_TILT_DEG:g} deg about x (measured from its target: "
        f"{measured.tilt_deg:.2f} deg, {measured.px_per_mm:.4f} px/mm), the same stretch on it, recovered lens; "
        f"|eyy| and |exx| t/b: the mean |error| over the points beyond {FAR_FRACTION:g} W above and below the "
        f"centre (the perspective's error changes sign there); L0 err: the centre extensometer's L0 in mm against "
        f"the truth on the plane (%)")
    say(f"{'lengths':<24}{'eyy ctr':>9}{'exx ctr':>9}{'|eyy| t/b':>10}{'|exx| t/b':>10}{'max crn':>9}"
        f"{'ext edge':>10}{'ext ctr':>9}{'L0 err':>9}")
    for name, row in errors.items():
        say(f"{name:<24}{row['eyy_centre']:>9.0f}{row['exx_centre']:>9.0f}{row['abs_eyy_far']:>10.0f}"
            f"{row['abs_exx_far']:>10.0f}{row['max_corners']:>9.0f}{row['edge']:>10.0f}{row['middle']:>9.0f}"
            f"{row['l0_error_pct']:>9.3f}")
    return errors


def _square_mm(spec, size: int) -> float:
    """A square side (mm) putting the whole plane target in 60 % of the image at SCALE_PX_PER_MM."""
    cols, rows = spec.inner_corners
    return float(np.floor(0.6 * size / SCALE_PX_PER_MM / (cols + 3) * 10.0) / 10.0)


def _parameters(lens: Lens, calibration: CameraCalibration) -> dict[str, tuple[float, float]]:
    K, T = calibration.camera_matrix, lens.camera_matrix
    names = ("k1", "k2", "p1", "p2")
    out = {"fx (px)": (T[0, 0], K[0, 0]), "fy (px)": (T[1, 1], K[1, 1]), "cx (px)": (T[0, 2], K[0, 2]),
           "cy (px)": (T[1, 2], K[1, 2])}
    out.update({name: (float(lens.dist_coeffs[i]), float(calibration.dist_coeffs[i])) for i, name in enumerate(names)})
    out["px/mm"] = (SCALE_PX_PER_MM, float(calibration.px_per_mm or np.nan))
    return {name: (float(a), float(b)) for name, (a, b) in out.items()}


def _strain_errors(lens: Lens, plane: _Plane, corrections: dict[str, dict]) -> dict[str, dict[str, float]]:
    """Errors of the strain field and two extensometers on a uniform stretch of ``plane`` (along the board's y,
    about the image's centre), per correction (``StrainConfig``'s calibration and scale)."""
    size = lens.size[0]
    centre = (size - 1) / 2.0
    pattern = SpecklePattern((size, size), density=1000.0 / 65536.0, radius=3.0, seed=5,
                             margin=int(0.1 * size) + 20)
    cy = plane.centre_mm[1]
    still = scene_on_plane(plane.homography, plane.centre_mm, (centre, centre), SCALE_PX_PER_MM)
    stretched = scene_on_plane(plane.homography, plane.centre_mm, (centre, centre), SCALE_PX_PER_MM,
                               lambda X, Y: (X, cy + (Y - cy) / (1.0 + STRETCH)))
    reference = render_through_lens(pattern, lens, still, noise=1.0, seed=1)
    deformed = render_through_lens(pattern, lens, stretched, noise=1.0, seed=2)
    edge = 2 * STEP
    xs, ys = np.meshgrid(np.arange(edge, size - edge, STEP, dtype=np.float64),
                         np.arange(edge, size - edge, STEP, dtype=np.float64))
    points = np.column_stack([xs.ravel(), ys.ravel()])
    found = measure(reference, deformed, points, subset=SUBSET, subpixel="icgn", radius=12)
    r = np.hypot(points[:, 0] - centre, points[:, 1] - centre)
    length = 0.4 * size
    extensometers = (Extensometer("edge", 3.0 * edge, centre - length / 2, 3.0 * edge, centre + length / 2),
                     Extensometer("middle", centre, centre - length / 2, centre, centre + length / 2))
    true_l0_mm = _length_on_plane(lens, plane, extensometers[1])
    out = {}
    for name, correction in corrections.items():
        stage = StrainConfig(window=WINDOW, extensometers=extensometers, **correction).place(
            points, p0=points[len(points) // 2], roi=(0, 0, size, size), step=STEP, subset=SUBSET,
            image_size=(size, size))
        strain, readings = stage.compute(found.u, found.v, found.ok)
        eyy, exx = 1e6 * (strain.eyy - STRETCH), 1e6 * strain.exx
        ok = strain.ok
        centre_points, corner_points = ok & (r < CENTRE_FRACTION * size), ok & (r > CORNER_FRACTION * size)
        far_points = ok & (np.abs(points[:, 1] - centre) > FAR_FRACTION * size)
        extensometer = 1e6 * (readings.eng_strain - STRETCH)
        out[name] = {"eyy_centre": float(np.mean(eyy[centre_points])), "exx_centre": float(np.mean(exx[centre_points])),
                     "eyy_corners": float(np.mean(eyy[corner_points])), "exx_corners": float(np.mean(exx[corner_points])),
                     "max_centre": float(np.max(np.abs(eyy[centre_points]))),
                     "max_corners": float(np.max(np.abs(eyy[corner_points]))),
                     "abs_eyy_far": float(np.mean(np.abs(eyy[far_points]))),
                     "abs_exx_far": float(np.mean(np.abs(exx[far_points]))),
                     "edge": float(extensometer[0]), "middle": float(extensometer[1]),
                     "l0_error_pct": 100.0 * ((stage.config.in_mm(readings.l0_px[1]) or np.nan) / true_l0_mm - 1.0)}
    return out


def _length_on_plane(lens: Lens, plane: _Plane, extensometer: Extensometer) -> float:
    """The true length (mm, on the plane) between an extensometer's ends seen at its image positions."""
    ideal = lens.undistort(np.array([[extensometer.x1, extensometer.y1], [extensometer.x2, extensometer.y2]]))
    board = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), np.linalg.inv(plane.homography)).reshape(-1, 2)
    return float(np.linalg.norm(board[1] - board[0]))
