"""Tests of stream/export/field_writer.py: which frames get maps, what is written per frame, the .pvd at the end,
nothing partial after a discard, stale pictures removed, and the recorded images looked up by time."""

import os

import cv2
import meshio
import numpy as np
import pytest

from livedic.stream.export.field_options import FieldOptions, quantities
from livedic.stream.export.field_writer import FieldReport, FieldWriter, RecordedImages, remove_stale

SHAPE = (60, 80)
STEP = 10.0
X0, Y0 = (a.ravel() for a in np.meshgrid(20.0 + STEP * np.arange(4), 15.0 + STEP * np.arange(3)))


def _values(i):
    n = X0.size
    return {"u": np.full(n, 0.5 * i), "v": np.zeros(n), "exx": np.full(n, 0.001 * i), "eyy": np.zeros(n),
            "exy": np.zeros(n), "zncc": np.full(n, 0.99), "point_id": np.arange(n)}


def _writer(folder, options, frames=5):
    shown = quantities()
    limits = {q: (-2.0, 2.0) for q in shown}
    return FieldWriter(str(folder), options, shown, limits, (X0, Y0), STEP, frames, title_note="t.mcap")


def _image(i):
    return np.random.default_rng(i).integers(0, 255, SHAPE, dtype=np.uint8)


def test_maps_of_every_nth_frame_the_reference_and_the_last(tmp_path):
    writer = _writer(tmp_path, FieldOptions(maps=("u",), every=2, video="", vtk=False), frames=6)
    assert [writer.wants_image(p) for p in range(6)] == [True, False, True, False, True, True]
    with_video = _writer(tmp_path, FieldOptions(maps=(), every=2, video="u", vtk=False), frames=6)
    assert all(with_video.wants_image(p) for p in range(6))


def test_each_frame_gets_its_maps_and_vtu_and_the_pvd_lists_them(tmp_path):
    writer = _writer(tmp_path, FieldOptions(maps=("u", "exx"), every=2, video="", vtk=True), frames=3)
    ok = np.ones(X0.size, dtype=bool)
    ok[5] = False
    for i in range(3):
        writer.add(i, 10 + i, 0.1 * i, _values(i), ok, _image(i) if i != 1 else None)
    writer.finish()
    report = writer.report
    assert (report.frames, report.maps, report.vtu, report.no_image) == (3, 4, 3, 0)
    assert sorted(os.listdir(tmp_path / "maps" / "u")) == ["u_000010.png", "u_000012.png"]
    picture = cv2.imread(str(tmp_path / "maps" / "exx" / "exx_000012.png"))
    assert np.array_equal(picture[picture.shape[0] - SHAPE[0]:, :SHAPE[1]][:10, :10, 0], _image(2)[:10, :10])
    mesh = meshio.read(tmp_path / "vtk" / "frame_000011.vtu")
    assert np.array_equal(mesh.point_data["u"], _values(1)["u"]) and mesh.point_data["ok"].tolist() == ok.tolist()
    assert not (mesh.cells_dict["triangle"] == 5).any() and len(mesh.cells_dict["triangle"]) > 0
    pvd = (tmp_path / "fields.pvd").read_text()
    assert pvd.count("<DataSet") == 3 and 'file="vtk/frame_000012.vtu"' in pvd and report.pvd.endswith("fields.pvd")
    assert report.written(writer.options) == "4 maps, 3 .vtu files and fields.pvd"


def test_a_frame_drawn_without_an_image_is_counted_and_has_no_map(tmp_path):
    writer = _writer(tmp_path, FieldOptions(maps=("u",), every=1, video="", vtk=False), frames=2)
    writer.add(0, 0, 0.0, _values(0), np.ones(X0.size, dtype=bool), None)
    assert writer.report.no_image == 1 and writer.report.maps == 0 and not (tmp_path / "maps").exists()


def test_the_video_has_every_frame_and_a_discard_leaves_no_partial_file(tmp_path):
    ok = np.ones(X0.size, dtype=bool)
    kept = tmp_path / "kept"
    kept.mkdir()
    writer = _writer(kept, FieldOptions(maps=(), video="u", vtk=False, video_fps=5.0), frames=3)
    for i in range(3):
        writer.add(i, i, 0.2 * i, _values(i), ok, _image(i))
    writer.finish()
    capture = cv2.VideoCapture(str(kept / "overlay_u.mp4"))
    assert capture.get(cv2.CAP_PROP_FRAME_COUNT) == 3 and capture.get(cv2.CAP_PROP_FPS) == 5.0
    assert writer.report.written(writer.options) == "overlay_u.mp4 (3 frames)"
    dropped = tmp_path / "dropped"
    dropped.mkdir()
    writer = _writer(dropped, FieldOptions(maps=(), video="u", vtk=False), frames=3)
    writer.add(0, 0, 0.0, _values(0), ok, _image(0))
    writer.discard()
    assert os.listdir(dropped) == []


def test_the_report_in_words():
    report = FieldReport(maps=1, vtu=2)
    assert report.written(FieldOptions(maps=("u",), video="", vtk=True)) == "1 map, 2 .vtu files"
    assert report.written(FieldOptions(maps=(), video="", vtk=False)) == ""


def test_remove_stale_removes_only_this_exports_kind_of_files(tmp_path):
    (tmp_path / "maps" / "u").mkdir(parents=True)
    (tmp_path / "maps" / "v").mkdir()
    (tmp_path / "vtk").mkdir()
    for name in ("maps/u/u_000001.png", "maps/u/mine.png", "maps/v/v_000001.png", "vtk/frame_000001.vtu",
                 "vtk/notes.txt"):
        (tmp_path / name).write_bytes(b"x")
    remove_stale(str(tmp_path), FieldOptions(maps=("u",), video="", vtk=True))
    left = sorted(os.path.relpath(os.path.join(top, n), tmp_path) for top, _, names in os.walk(tmp_path)
                  for n in names)
    assert left == ["maps/u/mine.png", "maps/v/v_000001.png", "vtk/notes.txt"]


def test_recorded_images_are_found_by_time_passing_over_frames_without_results(tmp_path):
    from livedic.acquire.base import Frame
    from livedic.acquire.recording.writer import Recorder
    path = tmp_path / "images.mcap"
    with Recorder(str(path), {"command": "test"}, start_time_ns=0) as recorder:
        for i in (0, 1, 2, 4):
            recorder.write_frame(Frame(i, 1000 * i, np.full((4, 6), i, np.uint8), "Mono8"))
    images = RecordedImages(str(path))
    assert images.at(0).image[0, 0] == 0
    assert images.at(2000).image[0, 0] == 2                  # frame 1 passed over
    assert images.at(3000) is None                           # no image at that time
    assert images.at(4000).index == 4
    assert images.at(5000) is None                           # past the end
