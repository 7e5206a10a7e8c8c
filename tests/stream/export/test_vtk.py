"""Tests of stream/export/vtk.py: one frame as a VTK unstructured grid, and the .pvd time series."""

import os
import xml.etree.ElementTree as ElementTree

import meshio
import numpy as np

from livedic.stream.export.vtk import pvd_text, vtu_mesh


def test_a_frame_round_trips_through_a_vtu_file(tmp_path):
    x, y = np.array([0.0, 10.0, 0.0, 10.0]), np.array([0.0, 0.0, 10.0, 10.0])
    values = {"u": np.array([0.1, np.nan, 0.3, 0.4]), "v": np.array([1e-17, 2.0, 3.0, 4.0]),
              "ok": np.array([1, 0, 1, 1], dtype=np.uint8)}
    mesh = vtu_mesh(x, y, values, np.array([0, 1, 2, 1, 3, 2]))
    path = tmp_path / "frame.vtu"
    mesh.write(path)
    back = meshio.read(path)
    assert np.array_equal(back.points, np.column_stack([x, y, np.zeros(4)]))
    assert np.array_equal(back.cells_dict["triangle"], [[0, 1, 2], [1, 3, 2]])
    for name, array in values.items():
        assert np.array_equal(back.point_data[name], array, equal_nan=True), name
    assert np.array_equal(back.point_data["displacement"], np.column_stack([values["u"], values["v"], np.zeros(4)]),
                          equal_nan=True)


def test_a_frame_without_triangles_is_points_only():
    mesh = vtu_mesh(np.array([1.0]), np.array([2.0]), {"u": np.array([0.0]), "v": np.array([0.0])}, np.empty(0))
    assert mesh.cells_dict["triangle"].shape == (0, 3) and mesh.points.tolist() == [[1.0, 2.0, 0.0]]


def test_pvd_lists_the_entries_in_order_with_exact_times_and_relative_files():
    text = pvd_text([(0.0, os.path.join("vtk", "frame_000000.vtu")), (0.1, os.path.join("vtk", "frame_000001.vtu")),
                     (1 / 3, os.path.join("vtk", "frame_000002.vtu"))])
    assert text.startswith('<?xml version="1.0"?>\n')
    root = ElementTree.fromstring(text.split("\n", 1)[1])
    assert (root.tag, root.get("type"), root.get("version")) == ("VTKFile", "Collection", "0.1")
    datasets = root.find("Collection").findall("DataSet")
    assert [float(d.get("timestep")) for d in datasets] == [0.0, 0.1, 1 / 3]
    assert [d.get("file") for d in datasets] == [f"vtk/frame_{i:06d}.vtu" for i in range(3)]
    assert ElementTree.fromstring(pvd_text([]).split("\n", 1)[1]).find("Collection").findall("DataSet") == []
