"""``livedic export``'s maps (PNG), overlay video and VTK files: the colours against the colour map of known
affine fields, the camera image where there is no value, the video read back, the VTK values and the .pvd
against the CSV files, and an export stopped by a signal."""

import csv
import json
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import cv2
import numpy as np
import pytest

from livedic.stream.cli import main
from tests.stream.export.conftest import partial_files

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
SAMPLE = os.path.join(REPO, "recordings", "sample-tensile.mcap")
SIZE = (200, 240)                       # image height, width
CENTRE = (120.0, 100.0)                 # the affine fields' fixed point (x, y)
UX, VY = -0.004, 0.01                   # per frame: u = i UX (X - cx), v = i VY (Y - cy)
FRAMES = 6
LOST_FRAME = 4                          # in this frame the points within 18 px of LOST_AT are not ok
LOST_AT = (150.0, 110.0)
U_RANGE, EYY_RANGE = (-1.5, 1.5), (0.0, 6.0)     # px, %


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv("LIVEDIC_DEBUG", raising=False)


def _exact_u(i, x):
    """u of frame ``i`` at the current (deformed) column ``x``: x = X + i UX (X - cx) solved for X."""
    a = i * UX
    return a * ((x + a * CENTRE[0]) / (1.0 + a) - CENTRE[0])


@pytest.fixture(scope="module")
def affine(tmp_path_factory):
    """A recording of a speckle image under a known affine stretch (e_xx = i UX, e_yy = i VY), tracked by
    livedic's tracker; in frame 4 the points near ``LOST_AT`` are made not ok (NaN), as lost points are."""
    from livedic.acquire.base import Frame
    from livedic.dic.speckle import SpecklePattern, affine, render
    from livedic.dic.tracking import Tracker
    from livedic.stream.session.points import build_points
    from livedic.acquire.recording.writer import Recorder

    path = tmp_path_factory.mktemp("affine") / "affine.mcap"
    pattern = SpecklePattern(SIZE, n_speckles=1400, radius=3.0, seed=3)
    images = [render(pattern, affine(ux=i * UX, vy=i * VY, centre=CENTRE), noise_sigma=0.5, noise_seed=i)
              for i in range(FRAMES)]
    roi, step = (50, 40, 140, 120), 10
    points, _, _ = build_points(SIZE, roi=roi, step=step, n_points=None, subset=21)
    params = {"subset": 21, "search": "improved-wso", "subpixel": "icgn", "seed_radius": 2, "refind_radius": 16,
              "refind_zncc": 0.8, "seed": 0}
    metadata = dict(params, command="livedic run", source_uri="test:affine", roi=list(roi), step=step,
                    point_ids="P0 is point 0")
    tracker = Tracker(images[0], points, **params)
    with Recorder(str(path), metadata, start_time_ns=0) as recorder:
        for i, image in enumerate(images):
            recorder.write_frame(Frame(i, i * 100_000_000, image, "Mono8"))
            m = tracker.track(image)
            u, v, ok = m.u.copy(), m.v.copy(), m.ok.copy()
            if i == LOST_FRAME:
                lost = np.hypot(m.x - LOST_AT[0], m.y - LOST_AT[1]) < 18
                u[lost], v[lost], ok[lost] = np.nan, np.nan, False
            recorder.write_results(i, i * 100_000_000, np.arange(m.u.size, dtype=np.uint32), m.x, m.y, u, v,
                                   m.zncc, ok, status=m.status.astype(np.int32), method="improved-wso+icgn",
                                   reference_frame_index=0)
    return str(path), images


@pytest.fixture(scope="module")
def exported(affine, tmp_path_factory):
    """Every map of every frame, the u video, the VTK files: ``livedic export`` with fixed u and e_yy ranges."""
    path, _ = affine
    out = tmp_path_factory.mktemp("export") / "out"
    code = main(["export", path, "-o", str(out), "--every", "1", "--video", "u", "--map-range",
                 f"u={U_RANGE[0]},{U_RANGE[1]}", "--map-range", f"eyy={EYY_RANGE[0]},{EYY_RANGE[1]}",
                 "--progress", "off"])
    assert code == 0
    return out


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _frame_rows(out, frame):
    return [row for row in _rows(out / "fields.csv") if int(row["frame"]) == frame]


def _camera_part(picture):
    """The camera image's part of a map: full resolution, at the bottom left."""
    return picture[picture.shape[0] - SIZE[0]:, :SIZE[1]]


def _colour_index(bgr):
    """The colour map's index (0..255) of each pixel's colour (the nearest of turbo's 256 colours)."""
    from matplotlib import colormaps
    lut = colormaps["turbo"](np.arange(256), bytes=True)[:, 2::-1].astype(np.int32)
    pixels = bgr.reshape(-1, 3).astype(np.int32)
    distance = ((pixels[:, None, :] - lut[None, :, :]) ** 2).sum(axis=2)
    return distance.argmin(axis=1).reshape(bgr.shape[:-1]), np.sqrt(distance.min(axis=1)).reshape(bgr.shape[:-1])


def _index_of(values, limits):
    """matplotlib's colour map index of ``values`` on ``limits`` (256 bins, the ends clipped)."""
    lo, hi = limits
    return np.clip(np.floor((np.asarray(values) - lo) / (hi - lo) * 256), 0, 255)


def _is_camera(part, image):
    """Pixels where the map shows the camera image unchanged (grey: B = G = R = the image)."""
    return (part == image[..., None]).all(axis=2)


def test_u_map_colours_are_the_colour_map_of_the_known_displacement(affine, exported):
    """Frame 5 (u = -0.02 (X - 120), up to 1.2 px): every painted pixel's colour is turbo's colour of the
    exact u at that pixel within 2 of 256 bins (0.023 px: the tracker's noise and the colour bins), and at
    each point's pixel the colour is that of its value in fields.csv."""
    _, images = affine
    part = _camera_part(cv2.imread(str(exported / "maps" / "u" / "u_000005.png")))
    painted = ~_is_camera(part, images[5])
    index, miss = _colour_index(part)
    assert miss[painted].max() == 0                    # opaque: colours straight from the map
    rows, cols = np.nonzero(painted)
    assert 0.15 < painted.mean() < 0.4 and cols.min() > 40 and cols.max() < 200   # the ROI, stretched by u
    exact = _index_of(_exact_u(5, cols), U_RANGE)
    assert np.abs(index[rows, cols] - exact).max() <= 2
    for row in _frame_rows(exported, 5):
        c, r = round(float(row["x"]) + float(row["u"])), round(float(row["y"]) + float(row["v"]))
        assert abs(index[r, c] - _index_of(float(row["u"]), U_RANGE)) <= 2, row


def test_eyy_map_is_the_uniform_strain_and_the_colour_bar_spans_the_range(affine, exported):
    """Frame 5: e_yy = 5 % everywhere (bin 213 of 256 on 0..6 %), within 2 bins (0.05 % of noise)."""
    _, images = affine
    picture = cv2.imread(str(exported / "maps" / "eyy" / "eyy_000005.png"))
    part = _camera_part(picture)
    painted = ~_is_camera(part, images[5])
    index, _ = _colour_index(part)
    assert np.abs(index[painted] - _index_of(5 * VY * 100, EYY_RANGE)).max() <= 2
    session = json.loads((exported / "session.json").read_text())
    ranges = session["livedic.export"]["fields"]["colour_ranges"]
    assert ranges["eyy"] == {"lo": 0.0, "hi": 6.0, "unit": "%", "fixed": True}
    assert ranges["u"]["unit"] == "px" and ranges["exx"]["fixed"] is False
    # The colour bar beside the image runs through the whole map, bottom (lo) to top (hi).
    bar = picture[picture.shape[0] - SIZE[0]:, SIZE[1]:]
    bar_index, bar_miss = _colour_index(bar)
    column = bar_index[:, np.argmax((bar_miss == 0).sum(axis=0))]
    exact_rows = np.flatnonzero(bar_miss[:, np.argmax((bar_miss == 0).sum(axis=0))] == 0)
    assert column[exact_rows].min() <= 5 and column[exact_rows].max() >= 250


def test_where_there_is_no_value_the_camera_image_shows(affine, exported):
    """Frame 4's lost points (NaN, not ok) and everything beyond the points: never a colour, the camera image
    unchanged; in the strain maps also the ok points around them whose window lost too many points."""
    _, images = affine
    rows = _frame_rows(exported, LOST_FRAME)
    lost = [row for row in rows if row["ok"] == "0"]
    assert len(lost) >= 6 and all(row["u"] == "nan" for row in lost)
    for quantity in ("u", "v", "exx", "eyy", "exy"):
        part = _camera_part(cv2.imread(str(exported / "maps" / quantity / f"{quantity}_{LOST_FRAME:06d}.png")))
        camera = _is_camera(part, images[LOST_FRAME])
        for row in lost:      # where the lost point is (its exact position) and 3 px around it
            x = float(row["x"]) + LOST_FRAME * UX * (float(row["x"]) - CENTRE[0])
            y = float(row["y"]) + LOST_FRAME * VY * (float(row["y"]) - CENTRE[1])
            r, c = round(y), round(x)
            assert camera[r - 3:r + 4, c - 3:c + 4].all(), (quantity, row["point_id"])
        assert camera[:30].all() and camera[-30:].all() and camera[:, :40].all()   # beyond the ROI
        if quantity.startswith("e"):
            no_strain = [row for row in rows if row["ok"] == "1" and row[quantity] == "nan"]
            for row in no_strain:
                c, r = round(float(row["x"]) + float(row["u"])), round(float(row["y"]) + float(row["v"]))
                assert camera[r, c], (quantity, row["point_id"])


def test_maps_every_n_frames_and_the_last(affine, tmp_path):
    path, _ = affine
    out = tmp_path / "out"
    assert main(["export", path, "-o", str(out), "--maps", "eyy,u", "--every", "4", "--video", "none", "--no-vtk",
                 "--progress", "off"]) == 0
    assert sorted(os.listdir(out / "maps")) == ["eyy", "u"]
    assert sorted(os.listdir(out / "maps" / "eyy")) == ["eyy_000000.png", "eyy_000004.png", "eyy_000005.png"]
    assert not (out / "vtk").exists() and not (out / "fields.pvd").exists()
    assert not [name for name in os.listdir(out) if name.endswith(".mp4")]


def test_the_video_has_every_frame_at_the_maps_size(exported):
    """Read back with OpenCV: one video frame per frame with results, the size of the maps, each frame the map
    of its frame (within the codec's loss)."""
    capture = cv2.VideoCapture(str(exported / "overlay_u.mp4"))
    frames = []
    while True:
        ok, image = capture.read()
        if not ok:
            break
        frames.append(image)
    assert len(frames) == FRAMES
    maps = [cv2.imread(str(exported / "maps" / "u" / f"u_{i:06d}.png")) for i in range(FRAMES)]
    assert all(frame.shape == maps[0].shape for frame in frames)
    assert maps[0].shape[0] % 2 == 0 and maps[0].shape[1] % 2 == 0
    assert capture.get(cv2.CAP_PROP_FPS) == 10.0
    for i, frame in enumerate(frames):
        errors = [np.abs(frame.astype(int) - other.astype(int)).mean() for other in maps]
        assert int(np.argmin(errors)) == i and errors[i] < 4.0, (i, errors)


def test_vtk_files_hold_the_csv_values_and_a_surface_without_lost_points(exported):
    """Each frame's .vtu (read by meshio): the reference points, and u, v, exx, eyy, exy, zncc, ok, status, the
    same numbers as fields.csv (bit for bit, NaN where it has nan); triangles only between ok points, none
    longer than 1.5 grid steps, covering the points."""
    import meshio
    rows = _rows(exported / "fields.csv")
    for frame in range(FRAMES):
        mesh = meshio.read(exported / "vtk" / f"frame_{frame:06d}.vtu")
        part = [row for row in rows if int(row["frame"]) == frame]
        ids = np.array([int(row["point_id"]) for row in part])
        assert np.array_equal(mesh.point_data["point_id"], ids)
        assert np.array_equal(mesh.points[:, 0], [float(row["x"]) for row in part])
        assert np.array_equal(mesh.points[:, 1], [float(row["y"]) for row in part]) and not mesh.points[:, 2].any()
        for name in ("u", "v", "exx", "eyy", "exy", "zncc"):
            want = np.array([float(row[name]) for row in part])
            assert np.array_equal(mesh.point_data[name], want, equal_nan=True), (frame, name)
        for name in ("ok", "status"):
            assert np.array_equal(mesh.point_data[name], [int(row[name]) for row in part]), (frame, name)
        assert np.array_equal(mesh.point_data["displacement"][:, :2], np.column_stack(
            [mesh.point_data["u"], mesh.point_data["v"]]), equal_nan=True)
        triangles = mesh.cells_dict["triangle"]
        ok = mesh.point_data["ok"].astype(bool)
        assert ok[triangles].all()
        corners = mesh.points[triangles][:, :, :2]
        edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)
        assert edges.max() <= 15.0
        covered = np.zeros(len(ok), dtype=bool)
        covered[triangles.ravel()] = True
        assert covered[ok].mean() > 0.99 and (frame != LOST_FRAME or not ok.all())


def test_pvd_lists_every_frame_with_its_time(exported):
    """fields.pvd is a VTK Collection: one DataSet per frame, in order, the file relative to it and the time of
    p0_trace.csv."""
    root = ElementTree.parse(exported / "fields.pvd").getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection" and root.get("version") == "0.1"
    datasets = root.find("Collection").findall("DataSet")
    trace = _rows(exported / "p0_trace.csv")
    assert [float(d.get("timestep")) for d in datasets] == [float(row["time_s"]) for row in trace]
    assert [d.get("file") for d in datasets] == [f"vtk/frame_{int(row['frame']):06d}.vtu" for row in trace]
    assert all((exported / d.get("file")).is_file() and d.get("part") == "0" for d in datasets)


def test_units_follow_scale_and_strain_unit(affine, tmp_path, capsys):
    path, _ = affine
    out = tmp_path / "out"
    assert main(["export", path, "-o", str(out), "--scale", "20", "--strain-unit", "microstrain", "--maps", "u,exx",
                 "--every", "5", "--video", "none", "--no-vtk", "--progress", "off"]) == 0
    ranges = json.loads((out / "session.json").read_text())["livedic.export"]["fields"]["colour_ranges"]
    assert ranges["u"]["unit"] == "mm" and ranges["exx"]["unit"] == "microstrain"
    # Automatic ranges cover the values (u to 1.2 px = 0.06 mm; e_xx to -2 % = -20,000 microstrain), round ends.
    assert ranges["u"]["lo"] <= -0.06 * 0.99 and ranges["u"]["hi"] >= 0.06 * 0.99
    assert -40000 <= ranges["exx"]["lo"] <= -20000 * 0.99


@pytest.mark.parametrize("options, words", [
    (["--maps", "exx,strain"], "--maps 'exx,strain': give quantities from u,v,exx,eyy,exy"),
    (["--video", "e1"], "--video 'e1': give one of u, v, exx, eyy, exy, or none"),
    (["--every", "0"], "--every 0: give a whole number of frames >= 1"),
    (["--map-range", "eyy=2,1"], "--map-range 'eyy=2,1': give Q=LO,HI"),
    (["--map-range", "e=0,1"], "--map-range 'e=0,1': give Q=LO,HI"),
    (["--map-opacity", "0"], "--map-opacity 0: give a number in (0, 1]"),
    (["--video-fps", "-5"], "--video-fps -5: give frames a second between 0 and 1000"),
])
def test_bad_field_options_are_one_line_and_nothing_is_written(options, words, tmp_path, capsys):
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["export", SAMPLE, "-o", str(out), *options]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livedic: error: ") and words in lines[0], lines
    assert not out.exists()


def test_overwrite_replaces_an_earlier_exports_pictures(affine, tmp_path, capsys):
    """The maps and .vtu files of an earlier export are refused without --overwrite and replaced with it: the
    folder then holds the new export's pictures only."""
    path, _ = affine
    out = tmp_path / "out"
    assert main(["export", path, "-o", str(out), "--maps", "v", "--every", "1", "--video", "none"]) == 0
    assert len(os.listdir(out / "maps" / "v")) == FRAMES
    (out / "vtk" / "notes.txt").write_text("mine\n")
    capsys.readouterr()
    assert main(["export", path, "-o", str(out), "--maps", "v", "--every", "5", "--video", "none"]) == 2
    assert "maps/v/" in capsys.readouterr().err
    assert main(["export", path, "-o", str(out), "--maps", "v", "--every", "5", "--video", "none", "--no-vtk",
                 "--overwrite"]) == 0
    assert sorted(os.listdir(out / "maps" / "v")) == ["v_000000.png", "v_000005.png"]
    assert (out / "vtk" / "notes.txt").read_text() == "mine\n"       # not ours: never touched


# --------------------------------------------------------------------------- stopping (export_recording's own
# stops at each stage: test_export.py)

@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_during_the_export_says_what_was_left_in_one_line(signum, code, tmp_path, signal_when):
    """A real ``livedic export`` of the shipped sample, signalled once its progress line says it is drawing:
    exit 128 + the signal, one line saying so and what the folder holds, the CSV files complete, no partial
    file, no video, no .pvd."""
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("LIVEDIC_DEBUG", None)
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "livedic.stream.cli", "export", SAMPLE, "-o", str(out),
                                "--every", "1", "--progress", "on"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               cwd=str(tmp_path), env=env)
    text, stdout = signal_when(process, lambda err: b"drawing maps, video and VTK" in err, signum)
    assert process.returncode == code, text
    lines = [line.split("\r")[-1] for line in text.splitlines() if "livedic" in line]
    assert len(lines) == 1 and "Traceback" not in text and stdout == b"", text
    assert lines[0].startswith(f"livedic: export stopped on {signal.Signals(signum).name} while drawing the maps, "
                               f"video and VTK (frame ") and "not written: overlay_eyy.mp4, fields.pvd" in lines[0]
    assert len(_rows(out / "p0_trace.csv")) == 24 and len(_rows(out / "fields.csv")) == 24 * 211
    assert json.loads((out / "session.json").read_text())["livedic.export"]["frames_with_results"] == 24
    assert partial_files(out) == [] and not (out / "fields.pvd").exists() and not (out / "overlay_eyy.mp4").exists()


def test_export_help_lists_the_field_options(capsys):
    """--help prints (the '%' of the strain unit must not break argparse's help formatting)."""
    assert main(["export", "--help"]) == 0
    text = capsys.readouterr().out
    assert all(option in text for option in ("--maps", "--every", "--video", "--no-vtk", "--map-range",
                                             "--strain-unit {%,microstrain}", "--progress"))
