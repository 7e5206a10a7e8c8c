"""``livedic run`` turns every bad option, URI or file into one line on stderr and exit code 2."""

import subprocess
import sys

import cv2
import numpy as np
import pytest

from tests.stream.conftest import refused_run

SMALL = "synthetic:tensile?size=96x160&frames=3&fps=1000"


@pytest.mark.parametrize("extra, message", [
    (["--roi", "0,0,5000,100"], "ROI 0,0,5000,100 extends beyond"),
    (["--roi", "10,10,-5,20"], "--roi width and height must be positive"),
    (["--roi", "1,2,3"], "--roi must be 4 comma-separated numbers"),
    (["--subset", "20"], "--subset must be an odd integer"),
    (["--step", "0"], "--step must be a positive number"),
    (["--frames", "0"], "--frames must be >= 1"),
    (["--search", "foo"], "unknown search method"),
    (["--subpixel", "bar"], "unknown sub-pixel method"),
    (["--prefilter", "gaussian:5"], "pre-filter 'gaussian:5': SIGMA must be > 0 and <= 2 px"),
    (["--prefilter", "median:3"], "unknown pre-filter 'median:3'"),
    (["--interpolation", "bspline9"], "unknown interpolation 'bspline9': choose one of bspline3, bspline5, bspline7"),
    (["--subpixel", "icgn2", "--interpolation", "bspline5"], "--interpolation bspline5 is not available with"),
    (["--source", "synthetic:nope"], "unknown synthetic model"),
    (["--source", "bogus://x"], "unknown source scheme"),
    (["--source", "synthetic:tensile?fps=abc"], "option fps"),
    (["--source", "images:/nonexistent/*.png"], "no image files match"),
    (["--source", "mcap:/nonexistent.mcap"], "does not exist"),
    (["--source", "stereo:synthetic:tensile"], "one source given, a stereo pair takes two"),
    (["--source", "stereo:synthetic:tensile,synthetic:tensile?seed=2,clock=sun"], "clock=sun: write clock=host"),
    (["--source", "stereo:synthetic:tensile,synthetic:tensile?seed=2"], "a stereo source needs the rig's calibration"),
    (["--points", "/nonexistent.csv"], "does not exist"),
    (["--color-range", "2,-2"], "--color-range 2,-2: LO must be below HI"),
    (["--color-range", "-1,-1"], "--color-range -1,-1: LO must be below HI"),
    (["--color-range", "-2"], "--color-range must be 2 comma-separated numbers"),
    (["--color-range", "-2,x"], "--color-range must be 2 comma-separated numbers"),
    (["--color-range=-inf,2"], "--color-range must be 2 comma-separated numbers"),
])
def test_bad_run_input_is_one_line_and_exit_2(extra, message):
    argv = ["run", "--viewer", "none", "--no-record", "--progress", "off", "--source", SMALL, *extra]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True, timeout=120)
    errors = [line for line in done.stderr.splitlines() if line.startswith("livedic: error")]
    assert done.returncode == 2, done.stderr
    assert len(errors) == 1 and message in errors[0], done.stderr
    assert "Traceback" not in done.stderr


def test_points_outside_the_image_are_a_clear_error(tmp_path):
    points = tmp_path / "points.csv"
    points.write_text("x,y\n40,60\n500,20\n")
    argv = ["run", "--viewer", "none", "--no-record", "--progress", "off", "--source", SMALL, "--points", str(points)]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "1 of the given points lie outside the 96x160 image (first: 500,20)" in done.stderr


def test_an_image_of_another_size_in_a_sequence_is_refused_before_the_session(tmp_path):
    """Not "camera lost" with a 2-frame recording after the first frames: bad input, found in the headers."""
    images = tmp_path / "images"
    images.mkdir()
    speckle = cv2.GaussianBlur(np.random.default_rng(3).integers(0, 256, (128, 160)).astype(np.uint8), (0, 0), 1.5)
    for i in range(5):
        assert cv2.imwrite(str(images / f"f_{i}.png"), speckle[:120] if i == 2 else speckle)
    error = refused_run(tmp_path, [], source=f"images:{images}/f_*.png")
    assert error == (f"livedic: error: {images}/f_2.png is 160x120 but the first image {images}/f_0.png is 160x128: "
                     f"every image of a sequence must have the same size (remove it, or crop all images alike)")


def test_a_file_that_is_no_video_is_one_line_with_nothing_from_ffmpeg(tmp_path):
    """FFmpeg's own lines ("moov atom not found") used to come first: the whole of stderr is livedic's one line."""
    fake = tmp_path / "clip.mp4"
    fake.write_text("not a video at all\n")
    argv = ["run", "--viewer", "none", "--no-record", "--progress", "off", "--source", f"video:{fake}"]
    done = subprocess.run([sys.executable, "-m", "livedic.stream.cli", *argv], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [f"livedic: error: video source {fake}: OpenCV could not open it (not a video, "
                                        f"or a codec FFmpeg lacks)"]
