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
