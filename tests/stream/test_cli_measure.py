"""``livedic measure``: the command-line contract (columns, options, errors)."""

import csv
import io

import cv2
import numpy as np
import pytest

from dic.speckle import SpecklePattern, render
from stream.cli import main

SHIFT = (1.4, 0.7)


@pytest.fixture(scope="module")
def image_pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pair")
    pattern = SpecklePattern((120, 140), n_speckles=260, seed=2)
    paths = {}
    for depth, ext in ((8, "png"), (16, "tif")):
        for name, disp in (("ref", None), ("def", SHIFT)):
            path = folder / f"{name}{depth}.{ext}"
            assert cv2.imwrite(str(path), render(pattern, disp, bit_depth=depth))
            paths[name, depth] = str(path)
    return paths


def _rows(text):
    return list(csv.DictReader(io.StringIO(text)))


@pytest.mark.parametrize("depth", [8, 16])
def test_grid_measurement_to_stdout(image_pair, capsys, depth):
    code = main(["measure", image_pair["ref", depth], image_pair["def", depth], "--grid", "30",
                 "--subpixel", "icgn", "--radius", "4"])
    out = capsys.readouterr().out
    assert code == 0
    header = out.splitlines()[0].split(",")
    assert header[:6] == ["x", "y", "u", "v", "zncc", "ok"]
    rows = _rows(out)
    assert len(rows) >= 9
    for row in rows:
        assert row["ok"] == "1"
        assert abs(float(row["u"]) - SHIFT[0]) < 0.02 and abs(float(row["v"]) - SHIFT[1]) < 0.02


def test_points_file_and_output_file(image_pair, tmp_path):
    points = tmp_path / "points.csv"
    points.write_text("x,y\n60,60\n70.4,50\n2,2\n")
    out = tmp_path / "out.csv"
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], "--points", str(points),
                 "--search", "exhaustive", "--subpixel", "improved-surface-fit", "--radius", "3", "-o", str(out)])
    assert code == 0
    rows = _rows(out.read_text())
    assert [(r["x"], r["y"], r["ok"]) for r in rows] == [("60.000000", "60.000000", "1"),
                                                        ("70.000000", "50.000000", "1"),
                                                        ("2.000000", "2.000000", "0")]
    assert rows[2]["u"] == "nan"


@pytest.mark.parametrize("extra, message", [
    (["--grid", "0"], "grid step"),
    (["--grid", "-5"], "grid step"),
    (["--grid", "20", "--subset", "20"], "odd"),
    (["--grid", "20", "--subset", "301"], "larger than the image"),
    (["--grid", "20", "--search", "nope"], "unknown search method"),
    (["--grid", "20", "--subpixel", "nope"], "unknown sub-pixel method"),
])
def test_bad_options_give_one_line_and_exit_2(image_pair, capsys, extra, message):
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], *extra])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_bad_files_give_one_line_and_exit_2(image_pair, tmp_path, capsys):
    garbage = tmp_path / "garbage.png"
    garbage.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    points = tmp_path / "bad.csv"
    points.write_text("a,b\n1,2\n")
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((50, 50), np.uint8))
    cases = [
        ["measure", str(tmp_path / "missing.png"), image_pair["def", 8], "--grid", "20"],
        ["measure", str(garbage), image_pair["def", 8], "--grid", "20"],
        ["measure", image_pair["ref", 8], image_pair["def", 8], "--points", str(points)],
        ["measure", image_pair["ref", 8], str(small), "--grid", "20"],
    ]
    for argv in cases:
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2, argv
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err


def test_colour_images_are_converted_with_a_note(image_pair, tmp_path, capsys):
    grey = cv2.imread(image_pair["ref", 8], cv2.IMREAD_UNCHANGED)
    colour = tmp_path / "colour.png"
    cv2.imwrite(str(colour), np.dstack([grey] * 3))
    code = main(["measure", str(colour), image_pair["def", 8], "--grid", "40", "--subpixel", "icgn", "--radius", "3"])
    captured = capsys.readouterr()
    assert code == 0
    assert "note" in captured.err
    assert all(row["ok"] == "1" for row in _rows(captured.out))


@pytest.mark.parametrize("fill", [0, 255], ids=["flat-black", "saturated"])
def test_flat_or_saturated_region_flags_its_points_and_the_rest_is_measured(tmp_path, capsys, fill):
    """Paint the left third of both images uniform: points there are not ok, with a status; the others exact."""
    pattern = SpecklePattern((120, 150), n_speckles=280, seed=5)
    reference, deformed = render(pattern, None, bit_depth=8), render(pattern, SHIFT, bit_depth=8)
    reference[:, :50] = fill
    deformed[:, :50] = fill
    paths = [str(tmp_path / "ref.png"), str(tmp_path / "def.png")]
    for path, image in zip(paths, (reference, deformed)):
        assert cv2.imwrite(path, image)
    code = main(["measure", *paths, "--grid", "20", "--subpixel", "icgn", "--radius", "4"])
    out = capsys.readouterr().out
    assert code == 0
    rows = _rows(out)
    inside = [r for r in rows if float(r["x"]) + 10 < 50]        # the whole subset is uniform
    outside = [r for r in rows if float(r["x"]) - 10 > 50 + 3]  # clear of the edge, shift included
    assert inside and outside
    assert all(r["ok"] == "0" and r["u"] == "nan" for r in inside)
    from dic.status import Status
    assert {int(r["status"]) for r in inside} == {int(Status.FLAT_REFERENCE)}
    for row in outside:
        assert row["ok"] == "1"
        assert abs(float(row["u"]) - SHIFT[0]) < 0.02 and abs(float(row["v"]) - SHIFT[1]) < 0.02
