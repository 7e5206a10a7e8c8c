"""``livedic noise-floor IMAGES...``: static images rendered with known noise give the noise floor it implies;
bad input is one line, exit 2, nothing written."""

import json
import math

import cv2
import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, render
from livedic.stream.cli.main import main

NOISE = 2.0          # grey levels
SUBSET = 21


@pytest.fixture(scope="module")
def static_images(tmp_path_factory):
    folder = tmp_path_factory.mktemp("static")
    pattern = SpecklePattern((160, 160), radius=3.0, seed=4)
    paths = []
    for k in range(6):
        image = render(pattern, None, bit_depth=8, noise_sigma=NOISE, noise_seed=k)
        path = folder / f"static_{k}.png"
        cv2.imwrite(str(path), image)
        paths.append(str(path))
    clean = render(pattern, None, bit_depth=None)
    return paths, clean


def test_the_noise_floor_of_static_images_is_the_noise_through_the_subset(static_images, tmp_path, capsys):
    paths, clean = static_images
    out = tmp_path / "floor.json"
    assert main(["noise-floor", *paths, "--grid", "8", "--subset", str(SUBSET), "--scale", "20",
                 "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "livedic noise-floor: 5 static image(s)" in printed and "noise      floor on 5 static frame(s)" in printed
    floor = json.loads(out.read_text())
    rows = {(row["quantity"], row["unit"]): row for row in floor["table"]}
    assert floor["frames_used"] == [1, 2, 3, 4, 5] and floor["images"] == paths
    # sigma / sqrt(sum g_x^2 over a subset), with g_x of the noise-free image in grey levels (8 bit)
    gx = np.gradient(255.0 * clean / clean.max(), axis=1)
    expected = NOISE / math.sqrt(np.median(cv2.boxFilter(gx ** 2, -1, (SUBSET, SUBSET), normalize=False)))
    for component in ("u", "v"):
        row = rows[(component, "px")]
        assert row["status"] == "ok" and row["points"] > 100
        assert 0.5 * expected < row["temporal_sd_mean"] < 2.0 * expected, (row, expected)
        assert 1.1 < row["spatial_sd"] / row["temporal_sd_mean"] < 1.9, row
        assert rows[(component, "mm")]["spatial_sd"] == pytest.approx(row["spatial_sd"] / 20)
        assert f"{row['spatial_sd']:.4f}" in printed
    for name in ("exx", "eyy", "exy"):
        assert rows[(name, "microstrain")]["status"] == "ok"


def test_the_prefilter_is_applied_and_said(static_images, tmp_path, capsys):
    paths, _ = static_images
    floors = {}
    for prefilter in ("none", "gaussian:0.80"):
        out = tmp_path / f"{prefilter}.json"
        assert main(["noise-floor", *paths[:3], "--grid", "16", "--prefilter", prefilter, "-o", str(out)]) == 0
        floors[prefilter] = json.loads(out.read_text())
    assert ", pre-filter gaussian:0.8, interpolation bspline3; " in capsys.readouterr().out
    assert [floors[key]["prefilter"] for key in floors] == ["none", "gaussian:0.8"]
    assert all(floors[key]["interpolation"] == "bspline3" for key in floors)
    assert floors["none"]["table"][0]["spatial_sd"] != floors["gaussian:0.80"]["table"][0]["spatial_sd"]


def test_bad_input_is_one_line_exit_2_and_nothing_written(static_images, tmp_path, capsys):
    paths, _ = static_images
    out = tmp_path / "floor.json"
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((64, 80), np.uint8))
    broken = tmp_path / "broken.png"
    broken.write_text("not an image")
    for argv, words in ((paths[:1], "at least 2 images"), ([paths[0], str(small)], "must have the same size"),
                        ([paths[0], str(broken)], "broken.png"),
                        ([paths[0], str(tmp_path / "missing.png")], "missing.png")):
        assert main(["noise-floor", *argv, "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0] and err[0].startswith("livedic: error:"), err
        assert not out.exists()
