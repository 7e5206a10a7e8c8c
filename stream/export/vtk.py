"""The fields as VTK for ParaView: one frame's unstructured grid (meshio) and the ``.pvd`` time series that
lists the frames.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ElementTree
from typing import TYPE_CHECKING, Iterable, Mapping

import numpy as np

if TYPE_CHECKING:
    import meshio


def vtu_mesh(x: np.ndarray, y: np.ndarray, values: Mapping[str, np.ndarray], triangles: np.ndarray) -> meshio.Mesh:
    """A ``meshio.Mesh`` of one frame: points at (x, y, 0), ``values`` (name -> (N,) array) as point data."""
    import meshio
    points = np.column_stack([x, y, np.zeros_like(x)]).astype(np.float64)
    point_data = {name: np.ascontiguousarray(array) for name, array in values.items()}
    point_data["displacement"] = np.column_stack([values["u"], values["v"], np.zeros_like(values["u"])])
    return meshio.Mesh(points, [("triangle", np.asarray(triangles, dtype=np.int64).reshape(-1, 3))],
                       point_data=point_data)


def pvd_text(entries: Iterable[tuple[float, str]]) -> str:
    """A ParaView collection (``.pvd``) of (time_s, relative file name) entries: a time series."""
    root = ElementTree.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    collection = ElementTree.SubElement(root, "Collection")
    for time_s, name in entries:
        ElementTree.SubElement(collection, "DataSet", timestep=repr(float(time_s)), group="", part="0",
                               file=name.replace(os.sep, "/"))
    ElementTree.indent(root)
    return '<?xml version="1.0"?>\n' + ElementTree.tostring(root, encoding="unicode") + "\n"
