"""A field drawn as a map over the camera image: the triangulated surface of the reference points, the
pixels each triangle covers, and the picture (image, title, colour bar) as a PNG (see ``field_export``'s
notes for how a map is drawn).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from livedic.stream.export.field_options import DEFAULT_OPACITY

if TYPE_CHECKING:
    from livedic.stream.export.field_options import Quantity


COLOUR_MAP = "turbo"
LONG_EDGE = 1.5             # x the grid step: a grid cell's diagonal is 1.41 steps

_SUBPIXEL_BITS = 4          # triangle corners drawn to 1/16 px
MIN_PANEL_HEIGHT = 240      # px: the colour bar's height at least, below an image smaller than that
PNG_COMPRESSION = 3         # zlib level: half the size of OpenCV's default for +40 ms a 1 MP map


@dataclass(frozen=True)
class SurfaceMesh:
    """Triangles over the reference points: Delaunay, without the ones that bridge a gap in the grid."""
    triangles: np.ndarray        # (T, 3) int32 point indices

    @classmethod
    def over(cls, x: np.ndarray, y: np.ndarray, step: float) -> SurfaceMesh:
        """The mesh of the points (x, y) on a grid of ``step`` px (no triangles for fewer than 3 in a plane)."""
        import matplotlib.tri as mtri
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        try:
            triangles = mtri.Triangulation(x, y).triangles.astype(np.int32)
        except (ValueError, RuntimeError):      # fewer than 3 points, or all on a line
            triangles = np.empty((0, 3), dtype=np.int32)
        corners = np.stack([x[triangles], y[triangles]], axis=-1)
        edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=-1).max(axis=1) if len(triangles) else []
        return cls(triangles[np.asarray(edges) <= LONG_EDGE * float(step)])

    def where(self, valid: np.ndarray) -> np.ndarray:
        """The triangles whose three corners are ``valid`` (N,) bool."""
        return self.triangles[np.asarray(valid, dtype=bool)[self.triangles].all(axis=1)]


def _twice_area(x, y, triangles):
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    return (x[b] - x[a]) * (y[c] - y[a]) - (x[c] - x[a]) * (y[b] - y[a])


class PixelWeights:
    """Which moved triangle covers each pixel of a frame, and the pixel's barycentric weights in it.

    Triangles are filled into an index image (OpenCV, corners to 1/16 px) rather than searched:
    a deformed mesh can fold where a point is wrong, which a triangle finder refuses, and one fill
    serves every quantity of the frame. A pixel's value is the weighted sum of its triangle's
    corner values, NaN where a corner has none.
    """

    def __init__(self, shape: tuple[int, ...], x: np.ndarray, y: np.ndarray, triangles: np.ndarray,
                 reference_area: np.ndarray) -> None:
        import cv2
        self.shape = tuple(shape[:2])
        area = _twice_area(x, y, triangles)
        # A triangle that flipped or collapsed is a wrong point, not a deformation: left out.
        keep = (area * np.sign(reference_area) > 1e-9) & np.isfinite(area)
        triangles = triangles[keep]
        index = np.full(self.shape, -1, dtype=np.int32)
        corners = np.round(np.stack([x[triangles], y[triangles]], axis=-1) * (1 << _SUBPIXEL_BITS)).astype(np.int32)
        for k, polygon in enumerate(corners):
            cv2.fillConvexPoly(index, polygon, k, lineType=cv2.LINE_8, shift=_SUBPIXEL_BITS)
        rows, cols = np.nonzero(index >= 0)
        which = triangles[index[rows, cols]]
        x0, y0 = x[which[:, 0]], y[which[:, 0]]
        dx1, dy1 = x[which[:, 1]] - x0, y[which[:, 1]] - y0
        dx2, dy2 = x[which[:, 2]] - x0, y[which[:, 2]] - y0
        det = dx1 * dy2 - dx2 * dy1
        px, py = cols - x0, rows - y0
        w1 = (px * dy2 - dx2 * py) / det
        w2 = (dx1 * py - px * dy1) / det
        self.rows, self.cols, self.corners = rows, cols, which
        self.weights = np.stack([1.0 - w1 - w2, w1, w2], axis=1)

    def sample(self, values: np.ndarray) -> np.ndarray:
        """(H, W) float64 image of the vertex ``values`` (N,), NaN where no triangle covers a pixel."""
        out = np.full(self.shape, np.nan)
        out[self.rows, self.cols] = np.einsum("ij,ij->i", np.asarray(values, dtype=np.float64)[self.corners],
                                              self.weights)
        return out


def overlay(gray: np.ndarray, values: np.ndarray, limits: tuple[float, float],
            opacity: float = DEFAULT_OPACITY) -> np.ndarray:
    """(H, W, 3) BGR: ``values`` (H, W; display unit, NaN: none) coloured on ``limits`` over the ``gray`` image."""
    import cv2
    from matplotlib import colormaps
    from matplotlib.colors import Normalize
    out = cv2.cvtColor(gray, cv2.COLOR_GRAY2BGR)
    painted = np.isfinite(values)
    colours = colormaps[COLOUR_MAP](Normalize(*limits)(values[painted]), bytes=True)[:, 2::-1]
    if opacity >= 1.0:
        out[painted] = colours
    else:
        out[painted] = np.round(opacity * colours + (1.0 - opacity) * out[painted]).astype(np.uint8)
    return out


class MapLayout:
    """The picture around a map: the camera image at the bottom left, a title above, the colour bar at the right.

    Sizes follow the image height, so the text stays legible on any camera; the picture's width and
    height are even (what video encoders need). Text is drawn by matplotlib, as little as it can be:
    the colour bar and the title's quantity and note once per quantity, the frame and time once per
    frame (shared by its quantities).
    """

    def __init__(self, image_shape: tuple[int, ...], title_note: str = "") -> None:
        self.height, self.width = (int(n) for n in image_shape[:2])
        self.panel_height = max(self.height, MIN_PANEL_HEIGHT)      # a small image: the bar still fits beside it
        self.font_px = float(np.clip(self.height / 55.0, 11.0, 30.0))
        self.title_height = int(round(3.4 * self.font_px))
        self.line_height = self.title_height // 2
        self.bar_width = int(round(9.0 * self.font_px))
        self.total_width = self.width + self.bar_width + (self.width + self.bar_width) % 2
        self.total_height = self.panel_height + self.title_height + (self.panel_height + self.title_height) % 2
        self.title_note = title_note
        self.margin = int(round(0.5 * self.font_px))
        self.frame_text_left = self.margin + int(round(4.5 * self.font_px))   # after the widest symbol, "e_xy"
        self._bars: dict[tuple[str, tuple[float, float]], np.ndarray] = {}
        self._headings: dict[str, np.ndarray] = {}
        self._frame_text = (None, None)

    def picture(self, coloured: np.ndarray, quantity: Quantity, limits: tuple[float, float], frame_index: int,
                time_s: float) -> np.ndarray:
        """The whole picture (H, W, 3 BGR) of one map: ``coloured`` from ``overlay``."""
        picture = np.full((self.total_height, self.total_width, 3), 255, dtype=np.uint8)
        top = self.total_height - self.panel_height
        picture[:top] = self._heading(quantity, top)
        picture[:self.line_height, self.frame_text_left:] = self._frame_line(frame_index, time_s)
        picture[self.total_height - self.height:, :self.width] = coloured
        picture[top:, self.width:self.width + self.bar_width] = self._bar(quantity, limits)
        return picture

    def _figure(self, width, height):
        from matplotlib.figure import Figure
        return Figure(figsize=(width / 100.0, height / 100.0), dpi=100, facecolor="white")

    def _text(self, width, height, lines):
        """A white strip of ``lines``: (text, x px, y from the top 0..1, size in font_px, bold), each shrunk to fit."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        figure = self._figure(width, height)
        renderer = FigureCanvasAgg(figure).get_renderer()
        for text, x, y, size, bold in lines:
            label = figure.text(x / width, 1.0 - y, text, ha="left", va="center", fontsize=0.72 * size * self.font_px,
                                weight="bold" if bold else "normal", color="black" if bold else "0.3")
            room = width - x - self.margin
            extent = label.get_window_extent(renderer).width
            if extent > room:
                label.set_fontsize(label.get_fontsize() * room / extent)
        return _rendered(figure)

    def _heading(self, quantity, height):
        """The title strip of ``quantity`` without the frame: its symbol (bold) over a note (meaning, recording)."""
        if quantity not in self._headings:
            note = f"{quantity.meaning}; {self.title_note}" if self.title_note else quantity.meaning
            self._headings[quantity] = self._text(self.total_width, height, [
                (quantity.symbol, self.margin, 0.25, 1.0, True), (note, self.margin, 0.72, 0.8, False)])
        return self._headings[quantity]

    def _frame_line(self, frame_index, time_s):
        """"frame N   t = T s" (bold), drawn once per frame."""
        key = (int(frame_index), float(time_s))
        if self._frame_text[0] != key:
            text = f"frame {int(frame_index)}   t = {time_s:.3f} s"
            strip = self._text(self.total_width - self.frame_text_left, self.line_height, [(text, 0, 0.5, 1.0, True)])
            self._frame_text = (key, strip)
        return self._frame_text[1]

    def _bar(self, quantity, limits):
        key = (quantity, tuple(limits))
        if key not in self._bars:
            from matplotlib import colormaps
            from matplotlib.cm import ScalarMappable
            from matplotlib.colors import Normalize
            figure = self._figure(self.bar_width, self.panel_height)
            points = self.font_px * 0.72
            margin = 1.5 * self.font_px / self.panel_height
            axes = figure.add_axes((0.12, 3 * margin, 1.8 * self.font_px / self.bar_width, 1 - 5 * margin))
            bar = figure.colorbar(ScalarMappable(Normalize(*limits), colormaps[COLOUR_MAP]), cax=axes,
                                  extend="both")
            bar.ax.tick_params(labelsize=points)
            bar.set_label(quantity.label, fontsize=points)
            figure.text(0.5, margin, "no colour: no value", ha="center", va="center", fontsize=0.75 * points,
                        color="0.3")
            self._bars[key] = _rendered(figure)
        return self._bars[key]


def _rendered(figure):
    """A matplotlib figure as a BGR array of its pixel size."""
    import cv2
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return cv2.cvtColor(np.asarray(canvas.buffer_rgba()), cv2.COLOR_RGBA2BGR)


def encode_png(picture: np.ndarray) -> bytes:
    import cv2
    ok, data = cv2.imencode(".png", picture, [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION])
    if not ok:
        raise RuntimeError("OpenCV could not encode a PNG")
    return data.tobytes()
