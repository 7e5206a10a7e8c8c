"""The second pass of ``livedic export``: ``FieldWriter`` writes each frame's maps, video frame and VTK file
as it comes (each file whole), from the recorded images (``RecordedImages``), and reports what it wrote.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Mapping

import numpy as np

from livedic.acquire.atomic_file import AtomicFile
from livedic.stream.view.camera_image import display_gray

from livedic.stream.export.field_maps import MapLayout, PixelWeights, SurfaceMesh, _twice_area, encode_png, overlay
from livedic.stream.export.field_options import (_MAP_NAME, _VTU_NAME, MAPS_FOLDER, PVD_FILE, QUANTITIES, VIDEO_FOURCC,
                                                 VIDEO_SUFFIX, VTK_FOLDER, map_name, video_name, vtu_name)
from livedic.stream.export.vtk import pvd_text, vtu_mesh

if TYPE_CHECKING:
    from livedic.acquire.base import Frame
    from livedic.stream.export.field_options import FieldOptions, Quantity


class RecordedImages:
    """The camera images of a recording, in order, looked up by the time of each frame with results.

    One pass over ``/camera/image`` (``acquire.recording.source.McapSource``, truncated files too): frames
    without results (dropped by a tracker that fell behind) are passed over, and a result whose
    frame's image is not in the file gets None.
    """

    def __init__(self, path: str) -> None:
        from livedic.acquire.recording.source import McapSource
        self._frames = iter(McapSource(path))
        self._next: Frame | None = None

    def at(self, timestamp_ns: int) -> Frame | None:
        """The ``acquire.base.Frame`` logged at ``timestamp_ns``, or None."""
        while True:
            if self._next is None:
                self._next = next(self._frames, None)
                if self._next is None:
                    return None
            if self._next.timestamp_ns > timestamp_ns:
                return None
            frame, self._next = self._next, None
            if frame.timestamp_ns == timestamp_ns:
                return frame


@dataclass
class FieldReport:
    """What ``FieldWriter`` has written (complete files only), for the command's last line and session.json."""
    maps: int = 0
    vtu: int = 0
    video_frames: int = 0
    video: str = ""
    pvd: str = ""
    frames: int = 0                   # frames gone through
    no_image: int = 0                 # frames with results but no camera image: no map, no video frame
    other_points: int = 0             # frames tracking other points than the reference's: left out

    def written(self, options: FieldOptions) -> str:
        """The outputs complete so far, as words."""
        parts = []
        if options.maps:
            parts.append(f"{self.maps} map{'s' if self.maps != 1 else ''}")
        if self.video:
            parts.append(f"{os.path.basename(self.video)} ({self.video_frames} frames)")
        if options.vtk:
            parts.append(f"{self.vtu} .vtu file{'s' if self.vtu != 1 else ''}"
                         + (f" and {PVD_FILE}" if self.pvd else ""))
        return ", ".join(parts)


class FieldWriter:
    """Draws and writes the maps, the video and the VTK files of a recording, one frame with results at a time.

    Parameters
    ----------
    directory : str
        The export folder (exists).
    options : FieldOptions
    shown : dict
        Quantity name -> ``Quantity``.
    limits : dict
        Quantity name -> (lo, hi), display unit (``ColourRanges.limits``).
    reference : (x, y) arrays
        The reference points (the first frame's), which the surface is built on.
    step : float
        Their grid step, px.
    frames : int
        Frames with results in the recording (the last one always gets maps).
    title_note : str
        Said at the right of every title (the recording, the strain measure).
    """

    def __init__(self, directory: str, options: FieldOptions, shown: Mapping[str, Quantity],
                 limits: Mapping[str, tuple[float, float]], reference: tuple[np.ndarray, np.ndarray], step: float,
                 frames: int, title_note: str = "") -> None:
        self.directory = directory
        self.options = options
        self.shown = shown
        self.limits = limits
        self.x0, self.y0 = (np.asarray(a, dtype=np.float64) for a in reference)
        self.mesh = SurfaceMesh.over(self.x0, self.y0, step)
        self.reference_area = _twice_area(self.x0, self.y0, self.mesh.triangles)
        self.frames = int(frames)
        self.title_note = title_note
        self.report = FieldReport()
        self._layout: MapLayout | None = None
        self._video = None
        self._video_file = None
        self._pvd: list[tuple[float, str]] = []

    # -- per frame

    def wants_image(self, position: int) -> bool:
        """Whether the ``position``-th frame with results (0 = reference) is drawn (maps or video)."""
        return bool(self.options.video) or bool(self._maps_of(position))

    def _maps_of(self, position):
        every = self.options.every
        if position % every == 0 or position == self.frames - 1:
            return self.options.maps
        return ()

    def add(self, position: int, frame_index: int, time_s: float, values: Mapping[str, np.ndarray], ok: np.ndarray,
            image: np.ndarray | None = None, pixel_format: str = "") -> None:
        """Write what frame ``position`` gets: ``values`` maps name -> (N,) array of every ``fields.csv`` column
        this writer uses (``u v exx eyy exy zncc`` and, when recorded, ``status``, ``point_id``); ``image`` is the
        camera image (None: none recorded, no map or video frame)."""
        ok = np.asarray(ok, dtype=bool)
        drawn = tuple(q for q in QUANTITIES if q in self._maps_of(position) or q == self.options.video)
        if drawn and image is None:
            self.report.no_image += 1
        elif drawn:
            self._draw(position, frame_index, time_s, values, ok, image, pixel_format, drawn)
        if self.options.vtk:
            self._write_vtu(frame_index, time_s, values, ok)
        self.report.frames += 1

    def _draw(self, position, frame_index, time_s, values, ok, image, pixel_format, drawn) -> None:
        gray = display_gray(np.asarray(image), pixel_format)     # as the live view shows it
        if self._layout is None:
            self._layout = MapLayout(gray.shape, self.title_note)
        layout = self._layout
        u, v = np.asarray(values["u"], dtype=np.float64), np.asarray(values["v"], dtype=np.float64)
        valid = ok & np.isfinite(u) & np.isfinite(v)
        keep = valid[self.mesh.triangles].all(axis=1)
        weights = PixelWeights(gray.shape, self.x0 + u, self.y0 + v, self.mesh.triangles[keep],
                               self.reference_area[keep])
        for name in drawn:
            quantity = self.shown[name]
            shown_values = np.where(valid, quantity.factor * np.asarray(values[name], dtype=np.float64), np.nan)
            coloured = overlay(gray, weights.sample(shown_values), self.limits[name], self.options.opacity)
            picture = layout.picture(coloured, quantity, self.limits[name], frame_index, time_s)
            if name in self._maps_of(position):
                self._write_map(name, frame_index, picture)
            if name == self.options.video:
                self._video_frame(picture)

    def _write_map(self, name, frame_index, picture) -> None:
        path = os.path.join(self.directory, map_name(name, frame_index))
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with AtomicFile(path, binary=True) as out:
            out.write(encode_png(picture))
            out.commit()
        self.report.maps += 1

    def _video_frame(self, picture):
        import cv2
        if self._video is None:
            self._video_file = AtomicFile(os.path.join(self.directory, video_name(self.options.video)), binary=True,
                                          suffix=VIDEO_SUFFIX)
            height, width = picture.shape[:2]
            self._video = cv2.VideoWriter(self._video_file.tmp, cv2.VideoWriter_fourcc(*VIDEO_FOURCC),
                                          self.options.video_fps, (width, height))
            if not self._video.isOpened():
                self.discard()
                raise RuntimeError(f"OpenCV cannot write {VIDEO_FOURCC} video here: use --video none")
        self._video.write(picture)
        self.report.video_frames += 1

    def _write_vtu(self, frame_index, time_s, values, ok) -> None:
        import meshio
        name = vtu_name(frame_index)
        path = os.path.join(self.directory, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        data = {key: np.asarray(values[key]) for key in ("u", "v", "exx", "eyy", "exy", "zncc")}
        data["ok"] = ok.astype(np.uint8)
        for key in ("status", "point_id"):
            if values.get(key) is not None:
                data[key] = np.asarray(values[key])
        with AtomicFile(path, binary=True) as out:
            # meshio writes by path (it opens the file itself): the temporary one, renamed when complete.
            meshio.write(out.tmp, vtu_mesh(self.x0, self.y0, data, self.mesh.where(ok)), file_format="vtu")
            out.commit()
        self._pvd.append((time_s, name))
        self.report.vtu += 1

    # -- the end

    def finish(self) -> None:
        """Close the video and write the ``.pvd`` (after the last frame)."""
        if self._video is not None:
            self._video.release()
            self._video = None
            self._video_file.commit()
            self.report.video = self._video_file.path
        if self.options.vtk:
            path = os.path.join(self.directory, PVD_FILE)
            with AtomicFile(path) as out:
                out.write(pvd_text(self._pvd))
                out.commit()
            self.report.pvd = path

    def discard(self) -> None:
        """Give up (an error or a stop): the unfinished video is removed; finished files stay."""
        if self._video is not None:
            self._video.release()
            self._video = None
        if self._video_file is not None and self._video_file.tmp is not None:
            self._video_file.discard()


def remove_stale(directory: str, options: FieldOptions) -> None:
    """Remove the maps and ``.vtu`` files of an earlier export that this one replaces (``--overwrite``), so the
    folder holds one export's pictures only; other files are never touched."""
    folders = [(os.path.join(directory, MAPS_FOLDER, q), _MAP_NAME) for q in options.maps]
    folders += [(os.path.join(directory, VTK_FOLDER), _VTU_NAME)] if options.vtk else []
    for folder, pattern in folders:
        if os.path.isdir(folder):
            for name in os.listdir(folder):
                if pattern.match(name):
                    os.unlink(os.path.join(folder, name))
