"""``livedic noise-floor --left ... --right ... --calibration RIG.json``: static pairs of the simulated stereo rig
(``synthetic:stereo``, zero strain, only each camera's noise changing) give U, V, W noise that the 2D noise and the
rig's geometry predict: the depth (W) about 1 / tan(half the angle between the cameras) times the in-plane (U);
bad input is one line, exit 2, nothing written."""

import json
import math

import cv2
import numpy as np
import pytest

from livedic.acquire.calibration import write_calibration
from livedic.acquire.sources import open_source
from livedic.stream.cli.main import main

PAIRS = 4                        # static pairs after the reference
ANGLE_DEG = 25.0                 # the simulated rig's angle between the cameras
FOCAL_PX, DISTANCE_MM = 1500.0, 300.0
VIEW = (f"synthetic:stereo?view={{}}&frames=2&static={PAIRS}&size=192x192&focal={FOCAL_PX:g}&angle={ANGLE_DEG:g}"
        f"&distance={DISTANCE_MM:g}&strain=0&neck=0&noise=1&pace=0")


@pytest.fixture(scope="module")
def static_pairs(tmp_path_factory):
    """The reference pair and PAIRS static pairs as PNGs in L/ and R/, the rig's exact calibration, the coupon's
    region in the left view."""
    folder = tmp_path_factory.mktemp("static_pairs")
    for view in ("left", "right"):
        source = open_source(VIEW.format(view))
        source.prepare()
        frames = iter(source)
        (folder / view[0].upper()).mkdir()
        for k in range(PAIRS + 1):
            cv2.imwrite(str(folder / view[0].upper() / f"static_{k}.png"), next(frames).image)
        if view == "left":
            roi = source.suggested_roi
    write_calibration(folder / "rig.json", source.scene.rig.calibration())
    write_calibration(folder / "left.json", source.scene.rig.calibration().left)
    return folder, ",".join(str(v) for v in roi)


def _args(folder, *extra):
    return ["noise-floor", "--left", str(folder / "L" / "*.png"), "--right", str(folder / "R" / "*.png"),
            "--calibration", str(folder / "rig.json"), *extra]


def test_static_pairs_give_depth_noise_larger_than_in_plane_by_the_rigs_geometry(static_pairs, tmp_path, capsys):
    folder, roi = static_pairs
    out = tmp_path / "floor.json"
    assert main(_args(folder, "--grid", "8", "--roi", roi, "-o", str(out))) == 0
    printed = capsys.readouterr().out
    assert f"livedic noise-floor: {PAIRS} static pair(s)" in printed and "U, V, W in space" in printed
    floor = json.loads(out.read_text())
    assert floor["frames_used"] == list(range(1, PAIRS + 1)) and floor["matched"] > 100
    rows = {(row["quantity"], row["unit"]): row for row in floor["table"]}
    U, V, W = (rows[(name, "mm")] for name in ("U", "V", "W"))
    for row in (U, V, W):
        assert row["status"] == "ok" and row["points"] > 100, row
        assert 0.0 < row["temporal_sd_mean"] < row["spatial_sd"] < 0.01, row       # small, non-zero, in mm
        assert abs(row["mean"]) < 0.3 * row["spatial_sd"], row                     # no bias: nothing moved
        assert f"{row['spatial_sd']:.5f}" in printed
    # each view's image noise (the left one's u, px) through the rig: in plane / sqrt(2) (two views) at
    # DISTANCE / FOCAL mm a pixel, the depth 1 / tan(half-angle) times that
    in_plane = rows[("u", "px")]["temporal_sd_mean"] * DISTANCE_MM / FOCAL_PX / math.sqrt(2)
    assert U["temporal_sd_mean"] == pytest.approx(in_plane, rel=0.35)
    ratio = W["temporal_sd_mean"] / U["temporal_sd_mean"]
    assert ratio == pytest.approx(1.0 / math.tan(math.radians(ANGLE_DEG / 2)), rel=0.3), ratio
    for name in ("exx", "eyy", "exy"):
        row = rows[(name, "microstrain")]
        assert row["status"] == "ok" and 0.0 < row["temporal_sd_mean"] < 1000.0, row


def test_bad_stereo_input_is_one_line_exit_2_and_nothing_written(static_pairs, tmp_path, capsys):
    folder, _ = static_pairs
    out = tmp_path / "floor.json"
    small = tmp_path / "small"
    small.mkdir()
    for k in range(PAIRS + 1):
        cv2.imwrite(str(small / f"static_{k}.png"), np.zeros((64, 80), np.uint8))
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for k, image in enumerate((cv2.imread(str(folder / "L" / "static_0.png")), np.zeros((64, 80), np.uint8))):
        cv2.imwrite(str(mixed / f"static_{k}.png"), image)
    left, right = str(folder / "L" / "*.png"), str(folder / "R" / "*.png")
    rig = str(folder / "rig.json")
    cases = (
        (["--left", left, "--right", str(folder / "R" / "static_[0-2].png"), "--calibration", rig],
         "--left gives 5 image(s) but --right 3"),
        (["--left", left, "--right", right, "--calibration", str(folder / "left.json")], "one-camera calibration"),
        (["--left", str(small / "*.png"), "--right", right, "--calibration", rig], "calibration was made for 192x192"),
        (["--left", str(mixed / "*.png"), "--right", str(folder / "R" / "static_[0-1].png"), "--calibration", rig],
         "must have the same size"),
        (["--left", left, "--calibration", rig], "--left is given without --right"),
        (["--left", left, "--right", right], "--calibration RIG.json"),
        (["--left", str(folder / "L" / "static_0.png"), "--right", str(folder / "R" / "static_0.png"),
          "--calibration", rig], "at least 2 pairs"),
        ([str(folder / "L" / "static_0.png"), "--left", left, "--right", right, "--calibration", rig], "not both"),
    )
    for argv, words in cases:
        assert main(["noise-floor", *argv, "-o", str(out)]) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0] and err[0].startswith("livedic: error:"), (argv, err)
        assert not out.exists()
