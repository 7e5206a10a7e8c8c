"""``livedic measure``: the command-line contract (columns, options, errors)."""

import csv
import io
import os

import cv2
import numpy as np
import pytest

from livedic.dic.speckle import SpecklePattern, render
from livedic.stream.cli import main
from livedic.stream.session.config import MeasureConfig

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


def test_the_prefilter_option_filters_both_images_as_dic_measure_does(image_pair, capsys):
    """``--prefilter`` reaches ``dic.measure``: the CSV is its result with the filter, and the shift still right."""
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.dic import measure
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], "--grid", "30", "--subpixel", "icgn",
                 "--radius", "4", "--prefilter", "gaussian:0.8"])
    rows = _rows(capsys.readouterr().out)
    assert code == 0 and all(row["ok"] == "1" for row in rows)
    points = [(float(row["x"]), float(row["y"])) for row in rows]
    images = [read_grey_image(image_pair[name, 8])[0] for name in ("ref", "def")]
    sampled = MeasureConfig(subpixel="icgn").interpolation               # measure's default with icgn
    expected = measure(*images, points, subpixel="icgn", radius=4, prefilter="gaussian:0.8", interpolation=sampled)
    unfiltered = measure(*images, points, subpixel="icgn", radius=4, interpolation=sampled)
    assert [float(row["u"]) for row in rows] == expected.u.tolist() != unfiltered.u.tolist()
    assert all(abs(float(row["u"]) - SHIFT[0]) < 0.02 and abs(float(row["v"]) - SHIFT[1]) < 0.02 for row in rows)


def test_the_interpolation_option_reaches_dic_measure(image_pair, capsys):
    """``--interpolation bspline5``: the CSV is ``dic.measure``'s quintic result (with measure's pre-filter for it),
    not the cubic one."""
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.dic import measure
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], "--grid", "30", "--subpixel", "icgn",
                 "--radius", "4", "--interpolation", "BSpline5"])
    rows = _rows(capsys.readouterr().out)
    assert code == 0 and all(row["ok"] == "1" for row in rows)
    points = [(float(row["x"]), float(row["y"])) for row in rows]
    images = [read_grey_image(image_pair[name, 8])[0] for name in ("ref", "def")]
    filtering = MeasureConfig(subpixel="icgn", interpolation="bspline5").prefilter
    expected = measure(*images, points, subpixel="icgn", radius=4, interpolation="bspline5", prefilter=filtering)
    cubic = measure(*images, points, subpixel="icgn", radius=4, prefilter=filtering)
    assert [float(row["u"]) for row in rows] == expected.u.tolist() != cubic.u.tolist()


def test_points_file_and_output_file(image_pair, tmp_path):
    points = tmp_path / "points.csv"
    points.write_text("x,y\n60,60\n70.4,50\n2,2\n")
    out = tmp_path / "out.csv"
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], "--points", str(points),
                 "--search", "exhaustive", "--subpixel", "improved-surface-fit", "--radius", "3", "-o", str(out)])
    assert code == 0
    rows = _rows(out.read_text())
    # every livedic CSV's number format: full precision (the shortest text that reads back the same double)
    assert [(r["x"], r["y"], r["ok"]) for r in rows] == [("60.0", "60.0", "1"), ("70.0", "50.0", "1"),
                                                        ("2.0", "2.0", "0")]
    assert rows[2]["u"] == "nan" and repr(float(rows[0]["u"])) == rows[0]["u"]


@pytest.mark.parametrize("extra, message", [
    (["--grid", "0"], "grid step"),
    (["--grid", "-5"], "grid step"),
    (["--grid", "20", "--subset", "20"], "odd"),
    (["--grid", "20", "--subset", "301"], "larger than the image"),
    (["--grid", "20", "--search", "nope"], "unknown search method"),
    (["--grid", "20", "--subpixel", "nope"], "unknown sub-pixel method"),
    (["--grid", "20", "--prefilter", "gaussian:0"], "SIGMA must be > 0 and <= 2 px"),
    (["--grid", "20", "--prefilter", "blur"], "unknown pre-filter 'blur'"),
    (["--grid", "20", "--interpolation", "spline"], "unknown interpolation 'spline'"),
    (["--grid", "20", "--interpolation", "bspline5"], "--interpolation bspline5 is not available with --subpixel "
                                                      "improved-surface-fit: use it with icgn"),
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
    grey = cv2.imread(image_pair["ref", 8], cv2.IMREAD_UNCHANGED).astype(np.float64)
    colour = tmp_path / "colour.png"
    tinted = [np.clip(grey * k, 0, 255).astype(np.uint8) for k in (0.8, 1.0, 1.1)]   # B, G, R differ: colour
    cv2.imwrite(str(colour), np.dstack(tinted))
    code = main(["measure", str(colour), image_pair["def", 8], "--grid", "40", "--subpixel", "icgn", "--radius", "3"])
    captured = capsys.readouterr()
    assert code == 0
    assert "colour image (3 channels) converted" in captured.err
    assert all(row["ok"] == "1" for row in _rows(captured.out))


@pytest.mark.parametrize("fmt", ["TIFF", "PNG"])
def test_a_grey_palette_image_is_read_as_grey_without_a_note(image_pair, tmp_path, capsys, fmt):
    """DIC Challenge images come as palette TIFFs whose entries are all grey: a grey image, exact, no note."""
    from PIL import Image
    grey = cv2.imread(image_pair["ref", 8], cv2.IMREAD_UNCHANGED)
    palette = Image.frombytes("P", grey.shape[::-1], grey.tobytes())
    palette.putpalette([level for level in range(256) for _ in range(3)])   # entry k = grey k
    path = tmp_path / f"palette.{fmt.lower()}"
    palette.save(path, format=fmt)
    assert Image.open(path).mode == "P"
    from livedic.acquire.files.image_file import read_grey_image
    image, note = read_grey_image(path)
    assert note is None and image.dtype == np.uint8 and np.array_equal(image, grey)
    code = main(["measure", str(path), image_pair["def", 8], "--grid", "40", "--subpixel", "icgn", "--radius", "3"])
    captured = capsys.readouterr()
    assert code == 0 and "note" not in captured.err and "converted" not in captured.err


def test_points_file_columns_are_carried_to_the_end_of_each_row(image_pair, tmp_path):
    points = tmp_path / "points.csv"
    points.write_text('id,x,label,y\n7,60,"gauge, left",60\n8,70.4,right,50\n9,2,corner,2\n')
    out = tmp_path / "out.csv"
    assert main(["measure", image_pair["ref", 8], image_pair["def", 8], "--points", str(points), "--search",
                 "exhaustive", "--subpixel", "icgn", "--radius", "3", "-o", str(out)]) == 0
    with open(out, newline="") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        rows = list(reader)
    assert header[:6] == ["x", "y", "u", "v", "zncc", "ok"] and header[-2:] == ["id", "label"]
    assert "status" in header and header.index("status") < header.index("id")
    assert [(row[0], row[1], row[-2], row[-1]) for row in rows] == [
        ("60.0", "60.0", "7", "gauge, left"), ("70.0", "50.0", "8", "right"),
        ("2.0", "2.0", "9", "corner")]


@pytest.mark.parametrize("variant", ["read-only", "denied", "under-a-file"])
def test_an_unwritable_output_fails_before_the_measurement_with_one_line(variant, tmp_path, capsys,
                                                                         monkeypatch, unwritable_folder):
    folder = unwritable_folder(variant)
    try:
        # The images do not exist: the output is checked first, so its problem is the one reported.
        code = main(["measure", str(tmp_path / "missing-ref.png"), str(tmp_path / "missing-def.png"), "--grid",
                     "20", "-o", str(folder / "out.csv")])
        err = capsys.readouterr().err
    finally:
        if folder.is_dir():
            folder.chmod(0o755)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livedic: error: cannot write -o ") and "internal" not in err
    assert "not writable" in lines[0] or "not a folder" in lines[0]


def test_output_to_a_folder_names_the_folder_not_a_temporary_file(image_pair, tmp_path, capsys):
    code = main(["measure", image_pair["ref", 8], image_pair["def", 8], "--grid", "40", "-o", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and f"-o {tmp_path} is a folder: give a file name" in err and ".livedic-" not in err
    assert len(err.strip().splitlines()) == 1


def test_output_file_gets_the_usual_permissions(image_pair, tmp_path):
    """Like replay and export: 0666 & ~umask (mkstemp alone would give 0600)."""
    from livedic.stream.output.files import current_umask
    out = tmp_path / "out.csv"
    previous = os.umask(0o022)
    try:
        assert current_umask() == 0o022
        assert main(["measure", image_pair["ref", 8], image_pair["def", 8], "--grid", "40", "-o", str(out)]) == 0
    finally:
        os.umask(previous)
    assert out.stat().st_mode & 0o777 == 0o644
    assert not [name for name in os.listdir(tmp_path) if name.startswith(".livedic-")]


def test_a_long_measurement_shows_progress_and_gives_the_same_numbers(image_pair, monkeypatch):
    """The progress line comes while dic.measure runs (here: until the line has been drawn), and the result
    is exactly one dic.measure call's."""
    import threading

    from livedic import dic
    from livedic.acquire.files.image_file import read_grey_image
    from livedic.stream.cli import MeasureProgress, measure_with_progress

    reference, _ = read_grey_image(image_pair["ref", 8])
    deformed, _ = read_grey_image(image_pair["def", 8])
    points = dic.grid_in_roi(reference.shape, None, 9, 21)
    method = dict(subset=21, search="improved-wso", subpixel="improved-surface-fit", radius=6, seed=3)
    direct = dic.measure(reference, deformed, points, **method)
    drawn = threading.Event()
    real = dic.measure

    def slow_measure(*args, **kwargs):
        result = real(*args, **kwargs)
        assert drawn.wait(30), "no progress line while the measurement ran"
        return result

    class Recording(MeasureProgress):
        def tick(self, elapsed_s):
            super().tick(elapsed_s)
            if self.lines:
                drawn.set()

    monkeypatch.setattr(dic, "measure", slow_measure)
    stream = io.StringIO()
    progress = Recording(len(points), "improved-wso + improved-surface-fit", in_place=True, after_s=0.0,
                         stream=stream)
    result = measure_with_progress(reference, deformed, points, progress=progress, tick_s=0.01, **method)
    text = stream.getvalue()
    assert f"measuring {len(points):,} points (improved-wso + improved-surface-fit)" in text
    assert f"measured {len(points):,} points" in text
    for name in ("x", "y", "u", "v", "zncc", "ok", "status"):
        assert np.array_equal(getattr(result, name), getattr(direct, name), equal_nan=name not in ("ok", "status"))


def test_progress_stays_quiet_for_short_measurements():
    from livedic.stream.cli import MeasureProgress
    stream = io.StringIO()
    progress = MeasureProgress(10, "m", in_place=False, after_s=1.5, every_s=15.0, stream=stream)
    for elapsed in (0.25, 0.5, 1.0, 1.25):
        progress.tick(elapsed)
    progress.done(1.3)
    assert stream.getvalue() == ""
    for elapsed in (1.5, 2.0, 10.0, 16.5, 17.0):      # a log gets a line now and then, not every tick
        progress.tick(elapsed)
    assert stream.getvalue().count("\n") == 2


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
    from livedic.dic.status import Status
    assert {int(r["status"]) for r in inside} == {int(Status.FLAT_REFERENCE)}
    for row in outside:
        assert row["ok"] == "1"
        assert abs(float(row["u"]) - SHIFT[0]) < 0.02 and abs(float(row["v"]) - SHIFT[1]) < 0.02


# ----------------------------------------------------------------------------- strain columns

@pytest.fixture(scope="module")
def affine_pair(tmp_path_factory):
    """A uniform stretch with a little shear: exx = 2e-3, eyy = -1e-3, exy = 0.3e-3 engineering; 8-bit, no added
    noise (quantisation only: the displacement error is then ~0.004 px RMS, the strain error ~5e-5 RMS)."""
    from livedic.dic.speckle import affine
    folder = tmp_path_factory.mktemp("affine")
    pattern = SpecklePattern((260, 260), n_speckles=1800, seed=5)
    field = affine(u=0.6, v=-0.3, ux=2e-3, uy=0.4e-3, vx=0.2e-3, vy=-1e-3, centre=(130.0, 130.0))
    paths = []
    for name, displacement in (("ref", None), ("def", field)):
        path = folder / f"{name}.png"
        assert cv2.imwrite(str(path), render(pattern, displacement))
        paths.append(str(path))
    return paths


@pytest.mark.parametrize("measure,truth", [
    ("engineering", (2e-3, -1e-3, 0.3e-3)),
    # Green-Lagrange of F = [[1.002, 0.0004], [0.0002, 0.999]]: (F^T F - I) / 2
    ("green", (2e-3 + 0.5 * (2e-3 ** 2 + 0.2e-3 ** 2), -1e-3 + 0.5 * (0.4e-3 ** 2 + 1e-3 ** 2),
               0.5 * (1.002 * 0.4e-3 + 0.2e-3 * 0.999))),
])
def test_strain_columns_of_a_uniform_stretch_are_within_2e_4(affine_pair, tmp_path, capsys, measure, truth):
    out = tmp_path / "strain.csv"
    capsys.readouterr()
    assert main(["measure", *affine_pair, "--grid", "10", "--subpixel", "icgn", "--strain-window", "7",
                 "--strain-measure", measure, "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"strain: {measure}, window 7 points x step 10 px + subset 21 = VSG 81 px" in err
    text = out.read_text()
    header = text.splitlines()[0].split(",")
    assert header[:7] == ["x", "y", "u", "v", "zncc", "ok", "status"] and header[-3:] == ["exx", "eyy", "exy"]
    rows = _rows(text)
    values = {name: np.array([float(r[name]) for r in rows]) for name in ("exx", "eyy", "exy")}
    x, y = (np.array([float(r[name]) for r in rows]) for name in ("x", "y"))
    ok = np.isfinite(values["exx"])
    assert ok.all() and all(r["ok"] == "1" for r in rows)     # edge points keep enough neighbours too
    # A full 7 x 7 window: 3 steps (30 px) from the grid's edges; nearer, the fits are one-sided and noisier.
    full = (x >= x.min() + 30) & (x <= x.max() - 30) & (y >= y.min() + 30) & (y <= y.max() - 30)
    assert full.sum() >= 200
    for name, want in zip(("exx", "eyy", "exy"), truth):
        error = values[name] - want
        # measured: RMS <= 6.3e-5, max 1.3e-4 with a full window, 2.7e-4 at the edges
        assert np.abs(error[full]).max() <= 2e-4, (name, np.abs(error[full]).max())
        assert np.abs(error).max() <= 5e-4 and np.sqrt(np.mean(error ** 2)) <= 1e-4, name
        assert abs(np.mean(error)) <= 3e-5, (name, np.mean(error))      # no bias: the right component and sign


def test_strain_columns_from_a_points_file_use_the_points_spacing(affine_pair, tmp_path, capsys):
    points = tmp_path / "points.csv"
    xs, ys = np.meshgrid(np.arange(40, 221, 12), np.arange(40, 221, 12))
    points.write_text("x,y,id\n" + "".join(f"{x},{y},p{i}\n" for i, (x, y) in enumerate(zip(xs.ravel(), ys.ravel()))))
    capsys.readouterr()
    assert main(["measure", *affine_pair, "--points", str(points), "--subpixel", "icgn",
                 "--strain-window", "5"]) == 0
    captured = capsys.readouterr()
    assert "strain: engineering, window 5 points x step 12 px + subset 21 = VSG 69 px" in captured.err
    header = captured.out.splitlines()[0].split(",")
    assert header[-4:] == ["exx", "eyy", "exy", "id"]         # the points file's columns stay last
    rows = _rows(captured.out)
    assert [r["id"] for r in rows] == [f"p{i}" for i in range(len(rows))]
    eyy = np.array([float(r["eyy"]) for r in rows])
    assert np.isfinite(eyy).all() and np.sqrt(np.mean((eyy + 1e-3) ** 2)) <= 1e-4 and np.abs(eyy + 1e-3).max() <= 5e-4


def test_without_the_strain_options_the_output_is_unchanged(affine_pair, capsys):
    """The strain columns are added before the points file's columns and change nothing else."""
    assert main(["measure", *affine_pair, "--grid", "40", "--subpixel", "icgn"]) == 0
    plain = capsys.readouterr().out
    assert main(["measure", *affine_pair, "--grid", "40", "--subpixel", "icgn", "--strain-window", "3"]) == 0
    with_strain = capsys.readouterr().out
    header = plain.splitlines()[0].split(",")
    assert header[:7] == ["x", "y", "u", "v", "zncc", "ok", "status"] and "exx" not in header
    stripped = [",".join(line.split(",")[:-3]) for line in with_strain.splitlines()]
    assert with_strain.splitlines()[0].split(",")[-3:] == ["exx", "eyy", "exy"]
    assert stripped == plain.splitlines()


@pytest.mark.parametrize("extra,message", [
    (["--strain-window", "4"], "--strain-window must be an odd number of points >= 3, got 4"),
    (["--strain-window", "1"], "--strain-window must be an odd number of points >= 3, got 1"),
    (["--strain-measure", "cauchy"], "invalid choice"),
])
def test_bad_strain_options_give_one_line_and_exit_2(affine_pair, tmp_path, capsys, extra, message):
    out = tmp_path / "never.csv"
    capsys.readouterr()
    assert main(["measure", *affine_pair, "--grid", "40", "-o", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert not out.exists()
