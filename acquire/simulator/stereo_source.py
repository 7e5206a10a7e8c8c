"""One camera of the simulated stereo test as a frame source: ``synthetic:stereo?view=left&...`` and ``view=right``.

Both views of one set of options show the same scene (``StereoScene``, built from the options alone), so
``stereo:synthetic:stereo?view=left&...,synthetic:stereo?view=right&...`` pairs them. Frames are rendered ahead
and delivered like the 2D simulator's (``static``, ``loop``, ``pace``); each frame's ``metadata["truth"]`` is
this camera's 2D truth (image displacement of the material seen at reference pixels), and ``truth3d`` the 3D one.
Options: docs/guide/sources.md ("The stereo test"); declared once in options.py (``STEREO_DEFAULTS``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion, CouponTruth
from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.options import convert_options, parse_synthetic_uri, rendered_count
from livedic.acquire.simulator.render import quantise
from livedic.acquire.simulator.sources import _PrerenderedSource
from livedic.acquire.simulator.stereo_force import forces_n
from livedic.acquire.simulator.stereo_force import specimen as coupon_specimen
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.acquire.simulator.stereo_scene import StereoScene

# The suggested region keeps this far inside the coupon's edges (mm) and the images' borders (px).
ROI_INSET_MM = 1.5
ROI_BORDER_PX = 16


def scene_from_options(options: dict[str, Any]) -> StereoScene:
    """The stereo scene typed stereo options describe (the same for both views)."""
    width, height = options["size"]
    lens = Lens((width, height), options["k1"], options["k2"], options["p1"], options["p2"],
                focal_px=options["focal"])
    rig = StereoRig.symmetric(lens, lens, distance_mm=options["distance"], angle_deg=options["angle"])
    motion = CouponMotion(rendered_count(options), strain=options["strain"], neck=options["neck"],
                          w0_mm=options["w0"], rot_x_deg=options["rotx"], rot_y_deg=options["roty"])
    return StereoScene(rig, Coupon(thickness_mm=options["thickness"]), motion, distance_mm=options["distance"],
                       facing=options["facing"], radius_px=options["radius"], seed=options["seed"],
                       bit=options["bit"], noise=options["noise"], supersample=options["supersample"])


class SyntheticStereoViewSource(_PrerenderedSource):
    """One camera (``view`` option) of the simulated stereo test, exact truth in 2D and 3D.

    Attributes
    ----------
    scene : StereoScene
        The scene both views show (rig, coupon, motion, pattern).
    view : {"left", "right"}
    lens : Lens
        This camera's lens (its focal length, distortion).
    suggested_roi : tuple of int, (x, y, w, h)
        The coupon in this view, inset from its edges, inside the image in every frame.
    """

    model_name = "stereo"

    def __init__(self, uri: str = "synthetic:stereo", **options: Any) -> None:
        model, raw = parse_synthetic_uri(uri)
        if model != "stereo":
            raise SourceError(f"{uri!r} is not a stereo URI: use synthetic:stereo?view=left|right&...")
        raw.update({k: v for k, v in options.items() if v is not None})
        opts = convert_options("stereo", raw)
        self.scene = scene_from_options(opts)
        self.view = opts["view"]
        super().__init__(opts, uri)
        self.lens = self.scene.lens(self.view)
        self.pattern = self.scene.pattern
        self._roi: tuple[int, int, int, int] | None = None

    def _pattern_margin(self) -> int:
        # The base class's image-sized pattern is replaced by the scene's (printed on the coupon): keep it small.
        return math.ceil(5.0 * self.options["radius"]) + 1

    def truth(self, frame_index: int, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Exact (u, v) px in this view of the material seen at reference pixels (x, y) (NaN off the coupon)."""
        return self.scene.image_displacement(self.view, self._check_index(frame_index), x, y)

    def truth3d(self, frame_index: int, material_xy: npt.ArrayLike) -> CouponTruth:
        """The 3D truth of material points (N, 2) mm in delivered frame ``frame_index`` (``StereoScene.truth`` of the
        rendered frame it shows: its ``frame`` is that one)."""
        return self.scene.truth(self._check_index(frame_index), material_xy)

    def forces_N(self) -> np.ndarray:  # noqa: N802 (the unit is part of the name, as in force_N columns)
        """The machine's force (N) in every delivered frame 0 .. frames - 1 (``stereo_force``: the coupon's law on its
        uniform strain; 0 in the static frames; cycled with ``loop``). Both views give the same."""
        return forces_n(self.scene.coupon, self.scene.motion, [self.rendered_index(i) for i in range(self.frames)])

    @property
    def specimen(self) -> dict[str, Any]:
        """The coupon's cross-section and force law (``stereo_force.specimen``)."""
        return coupon_specimen(self.scene.coupon, self.scene.motion)

    def _clean(self, i: int) -> np.ndarray:
        return self.scene.clean(self.view, i)

    def _render(self, i: int) -> np.ndarray:
        return quantise(self._clean(i), self.bit, self._noise_sigma(), self.scene.noise_seed(self.view, i))

    def _render_static(self, k: int) -> np.ndarray:
        if self._reference_clean is None:
            self._reference_clean = self._clean(0)
        return quantise(self._reference_clean, self.bit, self._noise_sigma(), self.scene.noise_seed(self.view, 0, k))

    @property
    def suggested_roi(self) -> tuple[int, int, int, int]:
        if self._roi is None:
            self._roi = self._coupon_box()
        return self._roi

    def _coupon_box(self) -> tuple[int, int, int, int]:
        """The largest box whose rows and columns all show the coupon ``ROI_INSET_MM`` inside its edges in the
        reference, and stay ``ROI_BORDER_PX`` inside the image in the last frame (on a grid of 4 px)."""
        H, W = self.shape
        step = 4
        y, x = np.mgrid[ROI_BORDER_PX:H - ROI_BORDER_PX:step, ROI_BORDER_PX:W - ROI_BORDER_PX:step].astype(np.float64)
        material = self.scene.material_at(self.view, 0, np.stack([x, y], axis=-1))
        inside = np.abs(material[..., 0]) <= 0.5 * self.scene.coupon.width_mm - ROI_INSET_MM
        u, v = self.scene.image_displacement(self.view, self.rendered_frames - 1, x, y)
        seen = (x + u >= ROI_BORDER_PX) & (x + u <= W - 1 - ROI_BORDER_PX) & (y + v >= ROI_BORDER_PX) & (
            y + v <= H - 1 - ROI_BORDER_PX)
        good = inside & seen
        rows = np.flatnonzero(good.any(axis=1))
        band = good[rows]
        if rows.size:
            x0 = x[0, band.argmax(axis=1).max()]                            # the rightmost left edge
            x1 = x[0, band.shape[1] - 1 - band[:, ::-1].argmax(axis=1).min()]  # the leftmost right edge
        if rows.size == 0 or x1 <= x0:
            raise SourceError(f"{self.uri}: the coupon is not in view (check distance=, focal=, angle=)")
        y0, y1 = y[rows[0], 0], y[rows[-1], 0]
        return (int(x0), int(y0), int(x1 - x0) + 1, int(y1 - y0) + 1)

    def frame_metadata(self, i: int) -> dict[str, Any]:
        meta = super().frame_metadata(i)
        meta["stereo_view"] = self.view
        return meta

    @property
    def settings(self) -> dict[str, Any]:
        settings = super().settings
        settings["stereo"] = {"view": self.view, "calibration": self.scene.rig.calibration().to_dict(),
                              "coupon": {"width_mm": self.scene.coupon.width_mm,
                                         "length_mm": self.scene.coupon.length_mm,
                                         "thickness_mm": self.scene.coupon.thickness_mm},
                              "pattern_px_per_mm": self.scene.pattern_px_per_mm}
        return settings
