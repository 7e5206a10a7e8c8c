"""The stereo test: a speckled coupon (coupon3d) moving in 3D, seen exactly by both cameras of a ``StereoRig``.

``StereoScene(rig, coupon, motion, ...)`` renders a frame's pair (``render``), gives the 3D truth of material
points (``truth``), where they appear in each view (``project``: the truth of the left-right match) and which
material each pixel shows (``material_at``). Every sample of a pixel is a ray cast onto the deformed surface
(stereo_render), the speckle summed at the material point it hits (``SpecklePattern.intensity``, exact), the
samples averaged (an area-integrating sensor), then the camera's noise and quantisation (render.quantise).
The pattern is printed on the coupon at ``pattern_px_per_mm``: its spots' radius is in px of the pattern.
"""

from __future__ import annotations

import math
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from livedic.acquire.simulator.coupon3d import Coupon, CouponMotion, CouponTruth
from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.options import FULL_SCALE
from livedic.acquire.simulator.render import paint, quantise
from livedic.acquire.simulator.sources import BACKGROUND_LEVEL, SPECKLE_DENSITY
from livedic.acquire.simulator.stereo_render import material_grid, ray_frame
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.dic.speckle import SpecklePattern

View = Literal["left", "right"]
VIEWS: tuple[View, View] = ("left", "right")
# Seeds the stereo views' camera noise (a stream of its own, one per view, test frame and static frame).
_STEREO_NOISE_SEED = 2027


def facing_placement(rig: StereoRig, distance_mm: float, facing: str) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, centre): the coupon's frame in the left camera's, its centre ``distance_mm`` down the left axis.

    ``facing="middle"``: its normal (-z) bisects the directions to both cameras (a stereo rig's usual set-up);
    ``"left"``: square to the left camera (the 2D set-up). x stays as close to the left camera's x as it can.
    """
    centre = np.array([0.0, 0.0, float(distance_mm)])
    to_left = -centre / np.linalg.norm(centre)
    if facing == "left":
        normal = to_left
    elif facing == "middle":
        right_centre = -rig.rotation.T @ rig.translation_mm
        to_right = (right_centre - centre) / np.linalg.norm(right_centre - centre)
        normal = (to_left + to_right) / np.linalg.norm(to_left + to_right)
    else:
        raise ValueError(f"facing must be 'middle' or 'left', got {facing!r}")
    z = -normal
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z]), centre


class StereoScene:
    """The coupon's test as both cameras see it.

    Parameters
    ----------
    rig : StereoRig
    coupon : Coupon
    motion : CouponMotion
    distance_mm : float
        The coupon's centre lies this far down the left camera's axis (a symmetric rig's aim point).
    facing : {"middle", "left"}
        See ``facing_placement``.
    radius_px, seed : float, int
        The speckle pattern's spot radius (pattern px) and seed.
    pattern_px_per_mm : float or None
        Pattern px per mm of the coupon; None: the left camera's scale at the coupon, focal / distance (so
        ``radius_px`` is about its size in the images).
    bit, noise, supersample : int, float, int
        8 or 12 bit; the noise's SD in grey levels of 8 bit; s x s samples averaged per pixel.
    """

    def __init__(self, rig: StereoRig, coupon: Coupon, motion: CouponMotion, *, distance_mm: float,
                 facing: str = "middle", radius_px: float = 4.0, seed: int = 0,
                 pattern_px_per_mm: float | None = None, bit: int = 8, noise: float = 1.0,
                 supersample: int = 1) -> None:
        self.rig = rig
        self.coupon = coupon
        self.motion = motion
        self.distance_mm = float(distance_mm)
        self.facing = facing
        self.placement, self.centre = facing_placement(rig, distance_mm, facing)
        self.pattern_px_per_mm = (float(rig.left.camera_matrix[0, 0]) / self.distance_mm
                                  if pattern_px_per_mm is None else float(pattern_px_per_mm))
        self.bit = int(bit)
        self.noise = float(noise)
        self.seed = int(seed)
        self.supersample = int(supersample)
        shape = (math.ceil(coupon.length_mm * self.pattern_px_per_mm), math.ceil(coupon.width_mm * self.pattern_px_per_mm))
        self.pattern = SpecklePattern(shape, density=SPECKLE_DENSITY, radius=radius_px, seed=seed,
                                      margin=math.ceil(5.0 * radius_px) + 2)

    @property
    def frames(self) -> int:
        return self.motion.frames

    @property
    def full_scale(self) -> int:
        return FULL_SCALE[self.bit]

    # -- geometry -----------------------------------------------------------
    def lens(self, view: View) -> Lens:
        return self.rig.left if view == "left" else self.rig.right

    def camera_pose(self, view: View) -> tuple[np.ndarray, np.ndarray]:
        """(R, t): the world (left camera frame) -> the camera's frame."""
        if view == "left":
            return np.eye(3), np.zeros(3)
        if view == "right":
            return np.asarray(self.rig.rotation, dtype=np.float64), np.asarray(self.rig.translation_mm, dtype=np.float64)
        raise ValueError(f"view must be 'left' or 'right', got {view!r}")

    def positions(self, frame: int, material_xy: npt.ArrayLike) -> np.ndarray:
        """Positions (N, 3) in the left camera frame (mm) of material points (N, 2) mm in ``frame``."""
        material = np.asarray(material_xy, dtype=np.float64).reshape(-1, 2)
        local = self.coupon.surface(self.motion.state(frame), material[:, 0], material[:, 1])
        return local @ self.placement.T + self.centre

    def truth(self, frame: int, material_xy: npt.ArrayLike) -> CouponTruth:
        """The exact 3D truth of material points (N, 2) mm in ``frame`` (``CouponTruth``)."""
        material = np.asarray(material_xy, dtype=np.float64).reshape(-1, 2)
        position = self.positions(frame, material)
        displacement = position - self.positions(0, material)
        return CouponTruth(frame, material, position, displacement, displacement @ self.placement,
                           self.coupon.strain(self.motion.state(frame), material[:, 0], material[:, 1]))

    def project(self, frame: int, material_xy: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Image positions (N, 2) px, (left, right), of material points (N, 2) mm in ``frame``, through the lenses."""
        world = self.positions(frame, material_xy)
        return self.project_world("left", world), self.project_world("right", world)

    def project_world(self, view: View, world: np.ndarray) -> np.ndarray:
        """Image positions (N, 2) of left-camera-frame points (N, 3) in ``view`` (``cv2.projectPoints``)."""
        R, t = self.camera_pose(view)
        lens = self.lens(view)
        pixels, _ = cv2.projectPoints(np.asarray(world, dtype=np.float64).reshape(-1, 1, 3), cv2.Rodrigues(R)[0], t,
                                      lens.camera_matrix, lens.dist_coeffs)
        return pixels.reshape(-1, 2)

    def material_at(self, view: View, frame: int, pixels: npt.ArrayLike) -> np.ndarray:
        """Material points (..., 2) mm seen at image positions ``pixels`` (..., 2) of ``view`` in ``frame``
        (NaN where the coupon is not)."""
        lens = self.lens(view)
        return self._material(view, frame, lens.undistort(np.asarray(pixels, dtype=np.float64)))

    def _material(self, view: View, frame: int, ideal: np.ndarray) -> np.ndarray:
        state = self.motion.state(frame)
        origin, M = ray_frame(*self.camera_pose(view), self.placement, self.centre, state)
        return material_grid(ideal, self.lens(view).camera_matrix, origin, M, self.coupon, state)

    def image_displacement(self, view: View, frame: int, x: npt.ArrayLike, y: npt.ArrayLike
                           ) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) px in ``view`` of the material seen at reference pixels (x, y): the 2D truth of one camera
        (NaN off the coupon)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        pixels = np.stack([x, y], axis=-1)
        material = self.material_at(view, 0, pixels).reshape(-1, 2)
        seen = np.full(material.shape, np.nan)
        on = np.all(np.isfinite(material), axis=1)
        if np.any(on):
            seen[on] = self.project_world(view, self.positions(frame, material[on]))
        moved = seen.reshape(pixels.shape) - pixels
        return moved[..., 0], moved[..., 1]

    # -- images -------------------------------------------------------------
    def clean(self, view: View, frame: int) -> np.ndarray:
        """``view``'s image of ``frame`` before noise and quantisation (float32 grey levels)."""
        lens = self.lens(view)
        s = self.supersample
        material = self._material(view, frame, lens.ideal_pixels(s))
        samples = np.full(material.shape[:2], self.full_scale * BACKGROUND_LEVEL)
        on = np.isfinite(material[..., 0])
        samples[on] = self.grey_at(material[on])
        width, height = lens.size
        return samples.reshape(height, s, width, s).mean(axis=(1, 3)).astype(np.float32)

    def grey_at(self, material_xy: npt.ArrayLike) -> np.ndarray:
        """The paint's grey level (float, before noise) at material points (N, 2) mm on the coupon."""
        material = np.asarray(material_xy, dtype=np.float64).reshape(-1, 2)
        scale = self.pattern_px_per_mm
        # pattern px: pixel centres at integers, the coupon's corner (-width / 2, -length / 2) at (-0.5, -0.5)
        px = (material[:, 0] + 0.5 * self.coupon.width_mm) * scale - 0.5
        py = (material[:, 1] + 0.5 * self.coupon.length_mm) * scale - 0.5
        return paint(self.pattern.intensity(px, py), float(self.full_scale))

    def noise_seed(self, view: View, frame: int, static: int = 0) -> tuple[int, ...]:
        """The camera noise's seed of ``view``'s test frame ``frame`` (``static`` k >= 1: its k-th static frame)."""
        return (self.seed, _STEREO_NOISE_SEED, VIEWS.index(view), static, frame)

    def render_view(self, view: View, frame: int) -> np.ndarray:
        """``view``'s image of ``frame`` as the camera gives it (uint8 or uint16)."""
        return quantise(self.clean(view, frame), self.bit, self.noise * self.full_scale / 255.0,
                        self.noise_seed(view, frame))

    def render(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) images of ``frame``, as the cameras give them."""
        return self.render_view("left", frame), self.render_view("right", frame)
