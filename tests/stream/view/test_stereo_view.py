"""Tests of stream/view/stereo_view.py and the logger's stereo entities: what a stereo session draws.
e_yy, the layout; read back from the saved .rrd.

The specimen is a plane tilted 20 degrees about the camera's x axis, 500 mm away; each frame moves its points
along the plane's normal by a known W (varying along the specimen) and in the plane by a known shift. In the
specimen's frame the reference points lie on z = 0, so every drawn point's z is its W, exactly, and W's colours
follow from the logged limits.
"""

from types import SimpleNamespace

import numpy as np

from livedic.acquire.base import Frame
from livedic.dic.stereo import StereoMeasurement, StereoPoints, StereoStatus, Triangulation
from livedic.stream.pipeline.frame_result import FrameResult, SessionStats
from livedic.stream.view import colour_scale, entities
from livedic.stream.view.logger import RerunLogger
from livedic.stream.view.process import ViewProcess
from livedic.stream.view.stereo_view import SPHERE_RADIUS_OF_SPACING
from tests.stream.view.test_logger import SHAPE, _lut_indices, _rows
from tests.stream.view.test_logger_strain import ROI, _points, _stage, _views

TILT = np.radians(20.0)
ROTATION = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(TILT), -np.sin(TILT)], [0.0, np.sin(TILT), np.cos(TILT)]])
MM_PER_PX = 0.1
W_PER_FRAME = 0.004            # W = W_PER_FRAME * frame * (specimen x in mm)
SHIFT_PER_FRAME = 0.05         # mm along the specimen's y
FRAMES = 6
LOST_3D = np.array([3, 40])    # points without a 3D position: seen by the right view (flagged by the epipolar bound)
LOST_RIGHT = np.array([7])     # ... and a point the right view lost
GREY = int(colour_scale.pack_colours([entities.NO_STRAIN_COLOUR])[0])


def _geometry():
    """Left image points, their specimen coordinates (mm, on the plane) and reference xyz (mm, camera frame)."""
    points = _points()
    plane = np.column_stack([(points[:, 0] - 160.0) * MM_PER_PX, (points[:, 1] - 120.0) * MM_PER_PX,
                             np.zeros(len(points))])
    return points, plane, plane @ ROTATION.T + [0.0, 0.0, 500.0]


def _stereo_result(i, eyy=None):
    """Frame ``i``: the pair (with a right image) and its StereoMeasurement; ``eyy``: the frame's e_yy field."""
    points, plane, reference = _geometry()
    n = len(points)
    w = W_PER_FRAME * i * plane[:, 0]
    displacement = (w[:, None] * ROTATION[:, 2] + SHIFT_PER_FRAME * i * ROTATION[:, 1])
    status = np.zeros(n, dtype=np.int8)
    status[LOST_3D] = StereoStatus.EPIPOLAR
    status[LOST_RIGHT] = StereoStatus.RIGHT_NOT_OK
    ok = status == StereoStatus.OK
    xyz = np.where(ok[:, None], reference + displacement, np.nan)
    nan = np.full(n, np.nan)
    stereo = StereoPoints(xyz=xyz, displacement=np.where(ok[:, None], displacement, np.nan), status=status,
                          triangulation=Triangulation(xyz, nan, nan, nan, status))
    right_ok = np.ones(n, dtype=bool)
    right_ok[LOST_RIGHT] = False
    right_xy = np.where(right_ok[:, None], points + [30.0, 2.0 * i], np.nan)
    zero = np.zeros(n)
    m = StereoMeasurement(x=points[:, 0], y=points[:, 1], u=zero, v=zero, zncc=np.full(n, 0.97),
                          ok=np.ones(n, dtype=bool), status=np.zeros(n, dtype=np.int8), right_xy=right_xy,
                          right_ok=right_ok, points=stereo)
    right = Frame(i, i * 20_000_000, np.full(SHAPE, 200, np.uint8), "Mono8")
    frame = Frame(i, i * 20_000_000, np.zeros(SHAPE, np.uint8), "Mono8", {}, right=right)
    return FrameResult(frame=frame, arrival_ns=i * 20_000_000, done_ns=i * 20_000_000 + 2_000_000,
                       processing_ns=1_000_000, measurement=m, is_reference=i == 0, frames_done=i + 1,
                       dropped_total=0, dropped_since_last=0, queue_depth=0, refound=0,
                       error_rms_px=float("nan"), error_max_px=float("nan"), strain=eyy)


def _strain_of(i):
    """A surface strain field: e_yy = 0.001 i along y, no strain at point 5 (too few neighbours)."""
    points, plane, _ = _geometry()
    has = np.ones(len(points), dtype=bool)
    has[5] = False
    return SimpleNamespace(eyy=np.where(has, 0.001 * i * (1.0 + plane[:, 1] / 10.0), np.nan), ok=has)


def _session(view, frames=FRAMES, strain=False):
    points = _points()
    view.start(image_shape=SHAPE, roi=ROI, p0_index=0, points=points, stereo=True)
    for i in range(frames):
        view(_stereo_result(i, _strain_of(i) if strain else None), SessionStats())
    view.close()


def test_the_3d_points_are_drawn_in_the_specimens_frame_with_w_along_its_normal(tmp_path):
    path = tmp_path / "stereo.rrd"
    _session(RerunLogger("save", str(path), image_max_side=max(SHAPE)))
    _, plane, _ = _geometry()
    ok = np.ones(len(plane), dtype=bool)
    ok[np.concatenate([LOST_3D, LOST_RIGHT])] = False
    positions = _rows(path, f"/{entities.SPACE_W}", "Points3D:positions")
    assert sorted(positions) == list(range(FRAMES))
    last = FRAMES - 1
    drawn = np.array(positions[last])
    assert drawn.shape == (ok.sum(), 3)                       # the ok points only, one call a frame
    # the plane's frame: x along the camera's x, y along the tilted plane's y, z its normal (away from the cameras)
    centred = plane[ok] - plane[ok].mean(axis=0)               # the origin: the reference points' centroid
    w = W_PER_FRAME * last * plane[ok, 0]
    np.testing.assert_allclose(drawn[:, 0], centred[:, 0], atol=1e-9)
    np.testing.assert_allclose(drawn[:, 1], centred[:, 1] + SHIFT_PER_FRAME * last, atol=1e-9)
    np.testing.assert_allclose(drawn[:, 2], w, atol=1e-9)
    # W's colours on W's automatic scale (grown from +-0.01 mm to nice numbers covering it), with its bar
    limits = _rows(path, f"/{entities.LIMITS_W}", "Scalars:scalars")
    assert limits[0] == [-colour_scale.MIN_COLOUR_LIMIT_MM, colour_scale.MIN_COLOUR_LIMIT_MM]
    lo, hi = limits[max(limits)]
    assert lo <= w.min() and w.max() <= hi and hi == colour_scale.nice_ceil(hi)
    assert sorted(_rows(path, f"/{entities.LEGEND_W}/bar", "Image:buffer")) == sorted(limits)
    colours = np.array(_rows(path, f"/{entities.SPACE_W}", "Points3D:colors")[last], dtype=np.int64)
    expected = np.clip(np.floor((w - lo) * (255 / (hi - lo)) + 0.5), 0, 255)
    # within one step of the map: W = 0 lands on the half-way rounding between two steps
    np.testing.assert_allclose(_lut_indices(colours), expected, atol=1)
    assert np.corrcoef(_lut_indices(colours), w)[0, 1] > 0.999
    # spheres that just touch: half the points' spacing on the specimen (the grid's 16 px = 1.6 mm)
    radii = _rows(path, f"/{entities.SPACE_W}", "Points3D:radii")[last]
    np.testing.assert_allclose(radii, [SPHERE_RADIUS_OF_SPACING * 16 * MM_PER_PX], rtol=1e-6)


def test_the_right_camera_shows_its_image_with_the_left_one_and_its_points_coloured_by_w(tmp_path):
    path = tmp_path / "right.rrd"
    # a live session's pacing: images at most 25 a second of frames 20 ms apart, every other frame
    _session(RerunLogger("save", str(path), image_max_side=max(SHAPE), image_max_hz=25.0))
    left = _rows(path, f"/{entities.CAMERA_IMAGE}", "Image:buffer")
    right = _rows(path, f"/{entities.CAMERA_RIGHT_IMAGE}", "Image:buffer")
    assert sorted(right) == sorted(left) == [0, 2, 4]
    assert set(np.asarray(right[2], dtype=np.uint8).ravel().tolist()) == {200}           # the right camera's own image
    where = _rows(path, f"/{entities.CAMERA_RIGHT_POINTS}", "Points2D:positions")
    colours = _rows(path, f"/{entities.CAMERA_RIGHT_POINTS}", "Points2D:colors")
    assert sorted(where) == list(range(FRAMES))                           # the points every frame
    points = _points()
    seen = np.ones(len(points), dtype=bool)
    seen[LOST_RIGHT] = False
    last = FRAMES - 1
    np.testing.assert_allclose(where[last], points[seen] + [30.0, 2.0 * last], atol=1e-6)
    # coloured as the 3D points by W; grey where the pair has no 3D point
    in_3d = np.ones(len(points), dtype=bool)
    in_3d[np.concatenate([LOST_3D, LOST_RIGHT])] = False
    right_colours = np.array(colours[last], dtype=np.int64)
    space = np.array(_rows(path, f"/{entities.SPACE_W}", "Points3D:colors")[last], dtype=np.int64)
    np.testing.assert_array_equal(right_colours[in_3d[seen]], space)
    assert set(right_colours[~in_3d[seen]]) == {GREY}


def test_the_3d_points_by_e_yy_share_the_e_yy_scale_and_are_grey_without_a_strain(tmp_path):
    path = tmp_path / "eyy.rrd"
    _session(RerunLogger("save", str(path), image_max_side=max(SHAPE)), strain=True)
    last = FRAMES - 1
    _, plane, _ = _geometry()
    ok = np.ones(len(plane), dtype=bool)
    ok[np.concatenate([LOST_3D, LOST_RIGHT])] = False
    colours = np.array(_rows(path, f"/{entities.SPACE_EYY}", "Points3D:colors")[last], dtype=np.int64)
    positions = _rows(path, f"/{entities.SPACE_EYY}", "Points3D:positions")[last]
    np.testing.assert_allclose(positions, _rows(path, f"/{entities.SPACE_W}", "Points3D:positions")[last])
    lo, hi = _rows(path, f"/{entities.LIMITS_EYY}", "Scalars:scalars")[last]
    strain = _strain_of(last)
    has = strain.ok[ok]
    assert colours[~has].tolist() == [GREY]                 # point 5
    expected = np.clip(np.floor((strain.eyy[ok][has] - lo) * (255 / (hi - lo)) + 0.5), 0, 255)
    np.testing.assert_allclose(_lut_indices(colours[has]), expected, atol=1)


def test_the_view_process_sends_the_right_image_and_draws_what_the_logger_draws(tmp_path):
    here, there = tmp_path / "here.rrd", tmp_path / "there.rrd"
    _session(RerunLogger("save", str(here), image_max_side=max(SHAPE)), frames=3)
    _session(ViewProcess("save", str(there), image_max_side=max(SHAPE)), frames=3)
    for entity, column in ((entities.CAMERA_RIGHT_IMAGE, "Image:buffer"), (entities.SPACE_W, "Points3D:positions"),
                           (entities.CAMERA_RIGHT_POINTS, "Points2D:positions")):
        mine, theirs = _rows(here, f"/{entity}", column), _rows(there, f"/{entity}", column)
        assert sorted(theirs) == sorted(mine) == [0, 1, 2], entity
        np.testing.assert_array_equal(np.asarray(theirs[2]), np.asarray(mine[2]))


def test_the_blueprint_has_the_right_camera_and_the_3d_views_only_in_a_stereo_session():
    stage = _stage(_points())
    for strain in (stage, None):
        two_d = _views(RerunLogger("save", "unused.rrd")._make_blueprint(True, strain))
        stereo = _views(RerunLogger("save", "unused.rrd")._make_blueprint(True, strain, stereo=True))
        assert not [v for v in two_d if v[0] == "Spatial3DView" or v[2] in (entities.CAMERA_RIGHT,
                                                                               entities.LEGEND_W)]
        spaces = [name for kind, name, origin in stereo if kind == "Spatial3DView"]
        assert spaces == (["3D by W (mm, out of plane)", "3D by e_yy (%)"] if strain
                          else ["3D by W (mm, out of plane)"])
        origins = [origin for _, _, origin in stereo]
        assert entities.CAMERA_RIGHT in origins and entities.LEGEND_W in origins
        # every 2D session's view is there too (the plots and the fields on the left image)
        assert {(kind, name) for kind, name, _ in two_d} <= {(kind, name) for kind, name, _ in stereo}
