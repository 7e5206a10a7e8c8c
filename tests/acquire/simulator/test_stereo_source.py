"""Tests of acquire/simulator/stereo_source.py: ``synthetic:stereo?view=left|right`` as two frame sources of one
scene, their options (round trip, refusals) and the truth their frames carry."""

import subprocess
import sys

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.options import STEREO_DEFAULTS
from livedic.acquire.simulator.stereo_source import SyntheticStereoViewSource
from livedic.acquire.sources import open_source
from livedic.dic.calibration import StereoCalibration

OPTIONS = ("frames=3&size=192x160&focal=1500&distance=250&angle=20&w0=0.5&rotx=1&roty=-0.5&strain=0.02&neck=0.05"
           "&facing=left&supersample=2&k1=-0.1&thickness=3&seed=5&radius=2&noise=0.5&pace=0")


def test_uri_options_round_trip_into_the_scene_and_the_settings():
    source = open_source(f"synthetic:stereo?view=right&{OPTIONS}", frames=4)
    assert isinstance(source, SyntheticStereoViewSource)
    options = source.options
    assert options["frames"] == 4 and options["size"] == (192, 160) and options["view"] == "right"
    assert (options["focal"], options["distance"], options["angle"], options["w0"], options["rotx"],
            options["roty"], options["strain"], options["neck"], options["facing"], options["supersample"],
            options["k1"], options["thickness"], options["seed"]) == (
        1500.0, 250.0, 20.0, 0.5, 1.0, -0.5, 0.02, 0.05, "left", 2, -0.1, 3.0, 5)
    scene = source.scene
    assert scene.motion.frames == 4 and scene.motion.w0_mm == 0.5 and scene.coupon.thickness_mm == 3.0
    assert source.lens is scene.rig.right and source.lens.camera_matrix[0, 0] == 1500.0 and source.lens.k1 == -0.1
    calibration = StereoCalibration.from_dict(source.settings["stereo"]["calibration"])
    assert calibration.angle_deg == pytest.approx(20.0)
    assert calibration.baseline_mm == pytest.approx(2 * 250.0 * np.sin(np.radians(10.0)))
    np.testing.assert_allclose(calibration.right.dist_coeffs, [-0.1, 0.0, 0.0, 0.0, 0.0])
    assert source.settings["stereo"]["view"] == "right" and source.settings["model"] == "stereo"
    defaults = open_source("synthetic:stereo").options
    assert {key: defaults[key] for key in STEREO_DEFAULTS} == STEREO_DEFAULTS


def test_both_views_show_one_scene_with_their_own_noise_and_carry_its_truth():
    left = open_source(f"synthetic:stereo?view=left&{OPTIONS}&static=1")
    right = open_source(f"synthetic:stereo?{OPTIONS}&static=1", view="right")
    np.testing.assert_array_equal(left.scene.pattern.centres, right.scene.pattern.centres)
    left_frames, right_frames = list(left), list(right)
    assert len(left_frames) == len(right_frames) == 4
    # delivered frame 3 is test frame 2; frame 1 the reference again, with new noise
    for view, frames in (("left", left_frames), ("right", right_frames)):
        np.testing.assert_array_equal(frames[3].image, left.scene.render_view(view, 2))
        assert frames[3].metadata["stereo_view"] == view
        difference = frames[1].image.astype(int) - frames[0].image.astype(int)
        assert 0 < np.count_nonzero(difference) and np.max(np.abs(difference)) <= 4
    # each view's 2D truth: the material seen at a reference pixel, projected in the frame
    material = np.array([[1.0, 2.0], [-4.0, -6.0]])
    for source, frames, index in ((left, left_frames, 0), (right, right_frames, 1)):
        before = source.scene.project(0, material)[index]
        after = source.scene.project(2, material)[index]
        u, v = frames[3].metadata["truth"](before[:, 0], before[:, 1])
        np.testing.assert_allclose(np.column_stack([u, v]), after - before, atol=1e-7)
        truth = source.truth3d(3, material)
        np.testing.assert_allclose(truth.position_mm, source.scene.positions(2, material))
        assert not source.visible(3, np.array([2.0]), np.array([2.0]))[0]     # a corner: background


def test_the_suggested_roi_lies_on_the_coupon_in_every_frame():
    for view in ("left", "right"):
        source = open_source(f"synthetic:stereo?view={view}&{OPTIONS}")
        x, y, w, h = source.suggested_roi
        assert w > 40 and h > 100
        corners = np.array([[x, y], [x + w - 1, y], [x, y + h - 1], [x + w - 1, y + h - 1]], dtype=float)
        for frame in range(source.frames):
            assert np.all(source.visible(frame, corners[:, 0], corners[:, 1]))


@pytest.mark.parametrize("query, words", [
    ("view=top", "option view='top': choose one of left, right"),
    ("supersample=5", "option supersample='5'"),
    ("angle=0", "option angle='0': must be between 0 and 90"),
    ("w0=abc", "option w0='abc'"),
    ("strain=1.5", "option strain='1.5'"),
    ("neck=1", "option neck='1'"),
    ("facing=right", "option facing='right'"),
    ("frames=1", "option frames='1'"),
    ("zoom=2", "unknown option(s) zoom for synthetic:stereo"),
])
def test_bad_options_are_one_source_error_naming_the_option(query, words):
    with pytest.raises(SourceError) as error:
        open_source(f"synthetic:stereo?{query}")
    assert words in str(error.value) and "\n" not in str(error.value)


def test_livedic_run_refuses_a_bad_stereo_option_in_one_line_with_exit_2():
    argv = ["run", "--viewer", "none", "--no-record", "--progress", "off", "--source", "synthetic:stereo?view=top"]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          timeout=120)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert done.returncode == 2, done.stderr
    assert len(errors) == 1 and "view='top'" in errors[0] and "Traceback" not in done.stderr


def test_twelve_bit_frames_are_the_eight_bit_ones_on_the_finer_scale():
    eight = open_source(f"synthetic:stereo?{OPTIONS}", noise=0, frames=2)
    twelve = open_source(f"synthetic:stereo?{OPTIONS}", noise=0, frames=2, bit=12)
    a, b = next(iter(eight)), next(iter(twelve))
    assert b.image.dtype == np.uint16 and b.pixel_format == "Mono12" and b.image.max() <= 4095
    np.testing.assert_allclose(b.image / 4095.0, a.image / 255.0, atol=0.6 / 255.0)


def test_a_looped_test_maps_delivered_frames_to_the_rendered_ones_in_2d_and_3d():
    source = open_source(f"synthetic:stereo?{OPTIONS}", frames=7, loop=3)
    assert source.scene.motion.frames == 3
    material = np.array([[2.0, -3.0]])
    # delivered 0 1 2 3 4 5 6 show rendered 0 1 2 1 0 1 2: the schedule spans the 3 rendered frames
    for delivered, rendered in ((2, 2), (3, 1), (4, 0), (6, 2)):
        np.testing.assert_array_equal(source.truth3d(delivered, material).position_mm,
                                      source.scene.positions(rendered, material))
    x, y = source.scene.project(0, material)[0].T
    np.testing.assert_array_equal(source.truth(3, x, y), source.scene.image_displacement("left", 1, x, y))
