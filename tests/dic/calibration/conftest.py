"""Calibration views rendered once per module through a known lens (the simulator's), for the tests to recover."""

import pytest

SIZE = (512, 512)
TRUE_LENS = {"k1": -0.12, "k2": 0.0, "p1": 0.0005, "p2": -0.0003}


@pytest.fixture(scope="session")
def chessboard_views():
    """(spec, square_mm, lens, [(name, image)], plane image at 2.0 px/mm) for chessboard:9x6, square 10 mm."""
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.targets import calibration_views, plane_view, render_target
    from livedic.dic.calibration import parse_target

    lens = Lens(SIZE, **TRUE_LENS)
    spec = parse_target("chessboard:9x6")
    views = [(f"view_{i}.png", render_target(spec, 10.0, lens, pose, seed=i))
             for i, pose in enumerate(calibration_views(spec, 10.0, lens))]
    plane = render_target(spec, 10.0, lens, plane_view(spec, 10.0, lens, 2.0), seed=99)
    return spec, 10.0, lens, views, plane


STEREO_SIZE = (640, 480)
# Two different lenses, both distorting: the right one longer and decentred differently.
STEREO_LENSES = ({"k1": -0.1, "k2": 0.02, "p1": 0.0004, "p2": -0.0002},
                 {"k1": -0.08, "p1": -0.0003, "p2": 0.0002, "focal_px": 660.0})


@pytest.fixture(scope="session")
def stereo_pairs():
    """(rig, spec, square_mm, [TargetPair]): chessboard:9x6 pairs rendered through a known 25-degree rig."""
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.stereo_rig import StereoRig
    from livedic.acquire.simulator.targets import render_target_pair, stereo_calibration_views, stereo_square_mm
    from livedic.dic.calibration import Detection, TargetPair, detect_target, parse_target

    rig = StereoRig.symmetric(Lens(STEREO_SIZE, **STEREO_LENSES[0]), Lens(STEREO_SIZE, **STEREO_LENSES[1]),
                              distance_mm=300.0, angle_deg=25.0)
    spec = parse_target("chessboard:9x6")
    square = stereo_square_mm(spec, rig, 0.45)
    pairs = []
    for i, pose in enumerate(stereo_calibration_views(spec, square, rig)):
        found = [detect_target(image, spec, square) for image in render_target_pair(spec, square, rig, pose, seed=i)]
        assert all(isinstance(f, Detection) for f in found)
        pairs.append(TargetPair(f"left_{i}.png", f"right_{i}.png", *found))
    return rig, spec, square, pairs


# The simulator's long-lens rig (synthetic:stereo's: 1024 px wide, f 8000 px, a 7 degree field; k1 -0.05 in both
# cameras, 25 degrees apart at 300 mm) and 9 of its narrow-field views (steep tilts, a board half the field wide).
NARROW_SIZE = (1024, 768)
NARROW_FOCAL_PX = 8000.0
NARROW_VIEW_COUNT = 9


def render_pairs(rig, spec, square, poses, seed=0):
    """[TargetPair] of ``poses`` rendered through ``rig`` (None where the target is not found)."""
    from livedic.acquire.simulator.targets import render_target_pair
    from livedic.dic.calibration import Detection, TargetPair, detect_target

    pairs = []
    for i, pose in enumerate(poses):
        found = [detect_target(image, spec, square)
                 for image in render_target_pair(spec, square, rig, pose, seed=seed + i)]
        pairs.append(TargetPair(f"left_{i}.png", f"right_{i}.png",
                                *(f if isinstance(f, Detection) else None for f in found)))
    return pairs


def narrow_rig():
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.stereo_rig import StereoRig

    lens = Lens(NARROW_SIZE, k1=-0.05, focal_px=NARROW_FOCAL_PX)
    return StereoRig.symmetric(lens, lens, distance_mm=300.0, angle_deg=25.0)


@pytest.fixture(scope="session")
def narrow_pairs():
    """(rig, spec, square_mm, [TargetPair]) of the long-lens rig, its views as ``stereo_view_plan`` gives them."""
    from livedic.acquire.simulator.targets import stereo_calibration_views, stereo_square_mm, stereo_view_plan
    from livedic.dic.calibration import parse_target

    rig = narrow_rig()
    spec = parse_target("chessboard:9x6")
    views, fill = stereo_view_plan(rig)
    square = stereo_square_mm(spec, rig, fill)
    poses = stereo_calibration_views(spec, square, rig, views[:NARROW_VIEW_COUNT])
    return rig, spec, square, render_pairs(rig, spec, square, poses)
