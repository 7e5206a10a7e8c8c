"""The set-up in the Rerun view: the region's outline on the camera view, and the set-up view as ``livedic preview``
draws it (docs/guide/live-view.md): logged once, static, when a session starts (``RerunLogger.log_setup``).
``SetupView.roi_label`` also names the ROI's box of a session without a set-up.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from livedic.stream.view.camera_image import display_image
from livedic.stream.view.entities import (
    CAMERA_ROI, CAMERA_ROI_LABEL, LABEL_CHARACTER, LABEL_GAP, LABEL_HEIGHT, LABEL_TEXT_COLOUR, MARKER_DRAW_ORDER, SETUP,
    SETUP_NOTES)

if TYPE_CHECKING:
    import rerun as rerun_sdk

# A stream.session.preview.SetupOverlay: not imported, even for typing (the session imports the view, and
# the packages of stream import one another without cycles: .importlinter)
SetupOverlay = Any


@dataclass(frozen=True)
class SetupView:
    """Draws a set-up into the stream ``rec`` (``rr``: the rerun module) at the view's display ``scale`` (the
    camera image shown at 1/scale), with the colour map ``lut`` and the camera image's larger side ``image_side``."""
    rr: ModuleType
    rec: rerun_sdk.RecordingStream
    scale: int
    lut: np.ndarray
    image_side: int

    def log(self, setup: SetupOverlay) -> None:
        """The set-up (a ``stream.session.preview.SetupOverlay``): the region's outline on the camera view, and the
        set-up view as ``livedic preview`` draws it (docs/guide/live-view.md). Static: logged once, at the start."""
        rr, rec = self.rr, self.rec
        preview = setup                 # the overlay carries the palette the preview draws in
        scale = float(self.scale)
        excluded = self._log_region(setup)
        labels = [((float(line[:, 0].max()), float(line[:, 1].min())), "excluded") for line in excluded]
        rec.log(f"{SETUP}/image", rr.Image(display_image(setup.image, setup.pixel_format, self.scale)), static=True)
        rec.log(f"{SETUP}/mig", rr.Image(self._contrast_image(setup)), static=True)
        points = setup.placement.points / scale
        colours = np.where(setup.weak[:, None], preview.WEAK_POINT_COLOUR, preview.POINT_COLOUR).astype(np.uint8)
        rec.log(f"{SETUP}/points", rr.Points2D(points, colors=colours, radii=-1.5), static=True)
        half = setup.subset / 2.0 / scale
        p0 = points[0]
        rec.log(f"{SETUP}/p0", rr.Boxes2D(mins=[p0 - half], sizes=[[2 * half, 2 * half]], colors=[preview.P0_COLOUR],
                                          radii=-1.5), static=True)
        labels.append(((float(p0[0] - half), float(p0[1] + half)), f"P0 ({setup.subset} px subset)"))
        labels += self._log_extensometers(setup)
        rec.log(f"{SETUP}/labels", self.label_points(labels), static=True)
        advice = setup.advice()
        notes = ["# set-up", "", *(f"- {line}" for line in setup.lines()), "",
                 "**check:**" if advice else "nothing to check: pattern, exposure and focus look fit for DIC",
                 *(f"- {line}" for line in advice)]
        rec.log(SETUP_NOTES, rr.TextDocument("\n".join(notes), media_type=rr.MediaType.MARKDOWN), static=True)

    def _log_region(self, setup: SetupOverlay) -> list[np.ndarray]:
        """The region's outline and exclusions on the camera view and the set-up view, with the region's name;
        returns the exclusions' strips (display px), which the caller labels."""
        rr, rec = self.rr, self.rec
        scale = float(self.scale)

        def strips(polylines: Sequence[np.ndarray]) -> list[np.ndarray]:
            return [np.asarray(line, dtype=np.float64) / scale for line in polylines]

        region = strips(setup.outlines)
        excluded = strips(setup.exclusions)
        outline = rr.LineStrips2D(region + excluded, radii=-1.5, colors=[setup.REGION_COLOUR] * len(region)
                                  + [setup.EXCLUDED_COLOUR] * len(excluded))
        # Rerun puts a strip's label at its middle, where P0 and the extensometers cross: the labels are
        # points of their own, at the ends ``livedic preview`` labels
        for path in (CAMERA_ROI, f"{SETUP}/region"):
            rec.log(path, outline, static=True)
        region_label = self.roi_label(setup.placement.bounds, setup.region_label)
        rec.log(CAMERA_ROI_LABEL, region_label, static=True)
        rec.log(f"{SETUP}/region/label", region_label, static=True)
        return excluded

    def _contrast_image(self, setup: SetupOverlay) -> np.ndarray:
        """RGBA of the speckle contrast per subset (MIG), colour-mapped inside the region, clipped pixels in the
        preview's colour; at the display's scale: this runs as the first frame is tracked, every ms of it a ms
        of latency."""
        quality, step = setup.quality, self.scale
        inside = setup.placement.region[::step, ::step]
        mig = quality.mig[::step, ::step]
        top = float(np.percentile(mig[inside], 99)) if inside.any() else 1.0
        index = np.clip(mig * (255.0 / max(top, 1e-6)), 0, 255).astype(np.uint8)
        rgba = np.empty(mig.shape + (4,), dtype=np.uint8)
        rgba[..., :3] = self.lut[index]
        rgba[..., 3] = np.where(inside, 150, 0)
        rgba[quality.clipped[::step, ::step] & inside] = (*setup.CLIPPED_COLOUR, 255)
        return rgba

    def _log_extensometers(self, setup: SetupOverlay) -> list[tuple[tuple[float, float], str]]:
        """The set-up's extensometers, in the preview's colours; returns their labels [((x, y), text)]."""
        if not setup.extensometers:
            return []
        rr, scale = self.rr, float(self.scale)
        palette = setup.EXTENSOMETER_COLOURS
        colours = [palette[k % len(palette)] for k in range(len(setup.extensometers))]
        self.rec.log(f"{SETUP}/extensometers",
                     rr.LineStrips2D([[(e.x1 / scale, e.y1 / scale), (e.x2 / scale, e.y2 / scale)]
                                      for e in setup.extensometers], colors=colours, radii=-2.0), static=True)
        labels = []
        for e in setup.extensometers:
            # the far end along x, the upper end along y: clear of the crossing at P0
            along_y = abs(e.y2 - e.y1) >= abs(e.x2 - e.x1)
            end = min(((e.x1, e.y1), (e.x2, e.y2)), key=lambda p: p[1] if along_y else -p[0])
            labels.append(((end[0] / scale, end[1] / scale), setup.extensometer_label(e)))
        return labels

    def label_points(self, labels: Sequence[tuple[tuple[float, float], str]]) -> Any:
        """Points2D that carry ``labels`` [((x, y) display px, text)]: dark text on Rerun's light label box."""
        rr = self.rr
        return rr.Points2D([xy for xy, _ in labels], labels=[text for _, text in labels],
                           colors=[LABEL_TEXT_COLOUR] * len(labels), radii=0.0, show_labels=True,
                           draw_order=MARKER_DRAW_ORDER + 2)

    def roi_label(self, bounds: Sequence[float], text: str) -> Any:
        """``text`` above the top-left corner of ``bounds`` (x, y, w, h; image px): clear of what is inside,
        however narrow the region (labels are drawn centred under their anchor)."""
        scale = self.scale
        x, y, _, _ = bounds
        left, top = x / scale - 0.5, y / scale - 0.5
        side = self.image_side / scale
        anchor = (left + 0.5 * len(text) * LABEL_CHARACTER * side, top - (LABEL_HEIGHT + LABEL_GAP) * side)
        return self.label_points([(anchor, text)])
