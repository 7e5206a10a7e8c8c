"""Simulated cameras with exactly known motion: a tensile test and plain translations.

``open_synthetic(uri)`` gives a ``SyntheticTensileSource`` or ``SyntheticTranslateSource``: every frame is
rendered ahead (``prepare``), then delivered paced at ``fps``, with the exact displacement in each frame's
``metadata["truth"]``. With ``static=N`` the test's first frame (the reference) is followed by N static frames:
the reference's image again with new camera noise, zero displacement, the reference's force; the test goes on
after them (``model_index``). URIs, options, the model and the force law: docs/guide/sources.md ("The simulator").
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from livedic.acquire.base import Frame, FrameSource, SourceError
from livedic.acquire.simulator.lens import Lens, lens_from_options
from livedic.acquire.simulator.model import FrameTruth, TensileModel
from livedic.acquire.simulator.options import (FULL_SCALE, convert_options, parse_synthetic_uri,
                                               rendered_count, resolve_tensile_options)
from livedic.acquire.simulator.render import PAINT_FLOOR, PAINT_GAIN, paint, quantise, render_specimen

_PIXEL_FORMAT = {8: "Mono8", 12: "Mono12"}
# Memory cap for the frames rendered ahead.
MAX_RENDER_BYTES = 4 << 30
# Speckles per pixel: the paper's 1000 spots on 256 x 256.
SPECKLE_DENSITY = 1000.0 / 65536.0
BACKGROUND_LEVEL = 0.10
# Seeds the speckles' fading rates (independent of the pattern, the jitter and the noise).
_FADE_SEED = 2025
# Seeds the static frames' noise: a stream of its own, so the test's frames keep their noise with or without them.
_STATIC_NOISE_SEED = 2026


# --------------------------------------------------------------------------- #
# Sources
# --------------------------------------------------------------------------- #

class _PrerenderedSource(FrameSource):
    """Renders every frame ahead (``prepare``), then delivers them paced at ``fps``.

    ``frames`` counts the frames delivered: the test's (``options["frames"]``) and the static ones after the
    reference (``static``).
    """

    model_name = ""

    def __init__(self, options: dict[str, Any], uri: str) -> None:
        self.options = options
        self.uri = uri
        width, height = options["size"]
        self.shape = (height, width)
        self.static = options["static"]
        self.test_frames = options["frames"]
        self.frames = self.test_frames + self.static
        self.rendered_frames = rendered_count(options)
        self.fps = options["fps"]
        self.bit = options["bit"]
        self.pixel_format = _PIXEL_FORMAT[self.bit]
        nbytes = (self.rendered_frames + self.static) * width * height * (1 if self.bit == 8 else 2)
        if nbytes > MAX_RENDER_BYTES:
            raise SourceError(
                f"{uri}: {self.rendered_frames} frames of {width}x{height} at {self.bit} bit need "
                f"{nbytes / 2**30:.1f} GiB rendered ahead (limit {MAX_RENDER_BYTES / 2**30:.0f} GiB): "
                "lower frames= or size=, or render fewer and cycle them with loop=K")
        self.lens: Lens | None = lens_from_options(options)
        self._images: list[np.ndarray] | None = None
        self._static_images: list[np.ndarray] = []
        self._reference_clean: np.ndarray | None = None
        self._lock = threading.Lock()
        self._closed = False
        self.render_seconds: float | None = None
        from livedic.dic.speckle import SpecklePattern
        self.pattern = SpecklePattern(self.shape, density=SPECKLE_DENSITY, radius=options["radius"],
                                      seed=options["seed"], margin=self._pattern_margin())

    def _pattern_margin(self) -> int | None:
        return None

    def truth(self, frame_index: int, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Exact (u, v) at reference points (x, y) in frame ``frame_index``, in image pixels.

        Through a lens: the point seen at x shows the scene point X = undistort(x), which moves to
        X + U(X) and is seen at distort(X + U(X)); its image displacement is that minus x.
        """
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        if self.lens is None:
            return self._scene_truth(frame_index, x, y)
        ideal = self.lens.undistort(np.stack([x, y], axis=-1))
        U, V = self._scene_truth(frame_index, ideal[..., 0], ideal[..., 1])
        seen = self.lens.distort(np.stack([ideal[..., 0] + U, ideal[..., 1] + V], axis=-1))
        return seen[..., 0] - x, seen[..., 1] - y

    def _scene_truth(self, frame_index: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact (U, V) of scene points at ideal positions (x, y) (each model says how)."""
        raise NotImplementedError

    def _ideal(self, x: npt.ArrayLike, y: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Ideal positions of image points (themselves without a lens)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        if self.lens is None:
            return x, y
        ideal = self.lens.undistort(np.stack([x, y], axis=-1))
        return ideal[..., 0], ideal[..., 1]

    def _clean(self, i: int) -> np.ndarray:
        """Test frame ``i`` before the camera's noise and quantisation (float32 grey levels)."""
        raise NotImplementedError

    def _render(self, i: int) -> np.ndarray:
        """Test frame ``i`` as the camera gives it."""
        return quantise(self._clean(i), self.bit, self._noise_sigma(), self.options["seed"] * 1_000_003 + i + 1)

    def _render_static(self, k: int) -> np.ndarray:
        """Static frame ``k`` (1..static): the reference with its own noise."""
        if self._reference_clean is None:
            self._reference_clean = self._clean(0)
        return quantise(self._reference_clean, self.bit, self._noise_sigma(),
                        (self.options["seed"], _STATIC_NOISE_SEED, k))

    @property
    def live(self) -> bool:
        return bool(self.options.get("pace", True))     # paced: a simulated camera

    @property
    def full_scale(self) -> int:
        return FULL_SCALE[self.bit]

    def _noise_sigma(self) -> float:
        return self.options["noise"] * self.full_scale / 255.0

    def prepare(self, progress: Callable[[int, int], object] | None = None) -> None:
        """Render the frames into memory (idempotent); ``progress(done, total)`` after each.

        ``rendered_frames`` of the test (all its frames, or ``loop`` when cycling), then the ``static`` ones.
        """
        with self._lock:
            if self._images is not None:
                return
            start = time.perf_counter()
            images = []
            total = self.rendered_frames + self.static
            for i in range(total):
                if self._closed:
                    raise SourceError(f"{self.uri}: closed while rendering")
                images.append(self._render(i) if i < self.rendered_frames
                              else self._render_static(i - self.rendered_frames + 1))
                if progress is not None:
                    progress(i + 1, total)
            self._images = images[:self.rendered_frames]
            self._static_images = images[self.rendered_frames:]
            self.render_seconds = time.perf_counter() - start

    def model_index(self, i: int) -> int:
        """The test's frame delivered as frame ``i``: 0 in the static frames (1..static), ``i - static`` after."""
        return 0 if i <= self.static else i - self.static

    def rendered_index(self, i: int) -> int:
        """The rendered test frame delivered as frame ``i``: its ``model_index``, or that index's place in the
        forward-back cycle (loop)."""
        i = self.model_index(i)
        k = self.rendered_frames
        if k >= self.test_frames:
            return i
        m = i % (2 * (k - 1))
        return m if m < k else 2 * (k - 1) - m

    def _check_index(self, frame_index: int) -> int:
        if not 0 <= frame_index < self.frames:
            raise ValueError(f"frame index {frame_index} outside 0..{self.frames - 1}")
        return self.rendered_index(frame_index)

    def frame_metadata(self, i: int) -> dict[str, Any]:
        return {"synthetic": self.model_name,
                "truth": FrameTruth(self.truth, i, f"synthetic:{self.model_name}", visible=self.visible)}

    def visible(self, frame_index: int, x: npt.ArrayLike, y: npt.ArrayLike, half_width: float = 0.0) -> np.ndarray:
        """Whether the square subset of half-width ``half_width`` px around each reference point (x, y)
        lies inside the image in the reference and in frame ``frame_index`` (boolean array)."""
        self._check_index(frame_index)
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        H, W = self.shape
        d = float(half_width)
        seen = np.ones(x.shape, dtype=bool)
        for dy in (-d, d):
            for dx in (-d, d):
                # truth maps the delivered index itself (static frames, loop): mapped twice it would be wrong
                u, v = self.truth(frame_index, x + dx, y + dy)
                for px, py in ((x + dx, y + dy), (x + dx + u, y + dy + v)):
                    seen &= (px >= 0.0) & (px <= W - 1.0) & (py >= 0.0) & (py <= H - 1.0)
        return seen

    def __iter__(self) -> Iterator[Frame]:
        self.prepare()
        period_ns = 1e9 / self.fps
        start_ns = time.monotonic_ns()
        images = cast(list[np.ndarray], self._images)       # prepare() rendered them
        for i in range(self.frames):
            image = (self._static_images[i - 1] if 1 <= i <= self.static
                     else images[self.rendered_index(i)])
            if self._closed:
                return
            metadata = self.frame_metadata(i)
            if i == 1:
                # the clock starts when the second frame is asked for: a session takes the first (its
                # reference) and prepares (points, outputs) before it asks for more, as a camera is started
                # when its consumer is ready; pacing from the first would hand the frames due meanwhile out
                # in a burst, which a dropping queue drops
                start_ns = time.monotonic_ns() - int(round(period_ns))
            if self.options["pace"]:
                due = start_ns + int(round(i * period_ns))
                wait = due - time.monotonic_ns()
                if wait > 0:
                    time.sleep(wait / 1e9)
                metadata["capture_monotonic_ns"] = due
            yield Frame(index=i, timestamp_ns=int(round(i * period_ns)), image=image,
                        pixel_format=self.pixel_format, metadata=metadata)

    def close(self) -> None:
        self._closed = True

    @property
    def settings(self) -> dict[str, Any]:
        width, height = self.options["size"]
        settings = {key: value for key, value in self.options.items() if key != "size"}
        settings.update({"model": self.model_name, "width": width, "height": height,
                         "pixel_format": self.pixel_format, "uri": self.uri,
                         "delivery": "rendered ahead, paced at fps" if self.options["pace"]
                         else "rendered ahead, as fast as read"})
        if self.rendered_frames < self.test_frames:
            settings["delivery"] += f"; {self.rendered_frames} rendered frames cycled forward and back"
        if self.lens is not None:
            settings["lens"] = self.lens.to_dict()
        return settings


class SyntheticTensileSource(_PrerenderedSource):
    """Simulated tensile test of a speckled dog-bone coupon (docs/guide/sources.md), exact truth.

    Parameters
    ----------
    uri : str, optional
        ``synthetic:tensile?...``; keyword options override the URI's.
    **options
        frames, fps, size (W, H) or "WxH", bit, noise, seed, radius, pace, loop, static, strain, neck, lateral,
        view, fade, fracture, modulus, thickness, scale, hardening, upper_yield, k1, k2, p1, p2.

    Attributes
    ----------
    model : TensileModel
    suggested_roi : tuple of int, (x, y, w, h)
        The gauge section, inset so subsets stay on the specimen while it narrows.
    fracture_frame : int or None
        The first delivered frame showing the specimen broken (``fracture`` option, counted in the test's
        frames, plus the ``static`` frames before it), None without one.
    specimen : dict
        A0 (mm^2), scale, E and the exact yield, Rp0.2 and Rm (``TensileModel.specimen``).
    """

    model_name = "tensile"

    def __init__(self, uri: str = "synthetic:tensile", **options: Any) -> None:
        model, raw = parse_synthetic_uri(uri)
        if model != "tensile":
            raise SourceError(f"{uri!r} is not a tensile URI: use synthetic:tensile?...")
        raw.update({k: v for k, v in options.items() if v is not None})
        opts = resolve_tensile_options(convert_options("tensile", raw))
        fracture = opts["fracture"] or None
        self.model = TensileModel((opts["size"][1], opts["size"][0]), rendered_count(opts), strain=opts["strain"],
                                  neck=opts["neck"], seed=opts["seed"], lateral=opts["lateral"], view=opts["view"],
                                  fracture_frame=fracture, modulus_gpa=opts["modulus"], hardening=opts["hardening"],
                                  upper_yield=opts["upper_yield"], thickness_mm=opts["thickness"],
                                  scale_px_per_mm=opts["scale"])
        self.fracture_frame = fracture + opts["static"] if fracture else None    # as delivered, after the static
        super().__init__(opts, uri)
        self._rows = np.arange(self.shape[0], dtype=np.float64)
        H = self.shape[0]
        self._background = BACKGROUND_LEVEL * (1.0 + 0.15 * (self._rows / H - 0.5))
        self._xs = np.ascontiguousarray(self.pattern.centres[:, 0])
        self._ys = np.ascontiguousarray(self.pattern.centres[:, 1])
        self._unfaded = np.ones(self._xs.shape[0])
        # Each speckle fades at its own rate (uniform 0..2 x the mean): the pattern changes, not only its contrast.
        self._fade_rates = (np.random.default_rng([opts["seed"], _FADE_SEED]).uniform(0.0, 2.0, self._xs.shape[0])
                            if opts["fade"] > 0.0 else None)

    @property
    def suggested_roi(self) -> tuple[int, int, int, int]:
        m = self.model
        inset = 0.15 * m.gauge_half + 8.0
        x0 = int(math.ceil(m.x_centre - m.gauge_half + inset))
        x1 = int(math.floor(m.x_centre + m.gauge_half - inset))
        y0 = int(math.ceil(m.gauge_top))
        y1 = int(math.floor(m.gauge_bottom))
        return (x0, y0, x1 - x0 + 1, y1 - y0 + 1)

    def _scene_truth(self, frame_index: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.model.displacement(self._check_index(frame_index), x, y)

    def force_N(self, frame_index: int) -> float:  # noqa: N802 (the unit is part of the name, as in force_N columns)
        """Force on the coupon in frame ``frame_index`` (N): E x e_el x A0, 0 from the fracture frame on."""
        return self.model.force_n(self._check_index(frame_index))

    def forces_N(self) -> np.ndarray:  # noqa: N802
        """Force (N) of every delivered frame 0 .. frames - 1 (float64 array; cycled with ``loop``)."""
        rendered = np.array([self.model.force_n(j) for j in range(self.rendered_frames)])
        return rendered[[self.rendered_index(i) for i in range(self.frames)]]

    @property
    def specimen(self) -> dict[str, Any]:
        """The model's specimen (``TensileModel.specimen``; its scale in ideal px/mm) and the lens, if any."""
        specimen = self.model.specimen
        if self.lens is not None:
            specimen["lens"] = self.lens.to_dict()
        return specimen

    def visible(self, frame_index: int, x: npt.ArrayLike, y: npt.ArrayLike, half_width: float = 0.0) -> np.ndarray:
        """Whether the square subset of half-width ``half_width`` px around each reference point (x, y) is
        fully seen in frame ``frame_index``: all specimen, on one side of the crack (once broken), inside
        the image in the reference and in that frame (boolean array; ``TensileModel.visible``; through a
        lens, judged at the points' ideal positions)."""
        return self.model.visible(self._check_index(frame_index), *self._ideal(x, y), half_width)

    def frame_metadata(self, i: int) -> dict[str, Any]:
        meta = super().frame_metadata(i)
        j = self.rendered_index(i)
        st = self.model.state(j)
        meta.update({"phase": st["phase"], "nominal_strain": self.model.nominal_strain(j),
                     "force_N": self.model.force_n(j)})
        if self.fracture_frame is not None:
            meta["fracture_frame"] = self.fracture_frame
        return meta

    def fade_amplitudes(self, i: int) -> np.ndarray:
        """Optical density factor of every speckle in frame ``i``: 1 - fade r_k e_p(y_k) / (strain + neck), >= 0.

        ``r_k`` is the spot's seeded rate (uniform 0..2), ``e_p(y_k)`` the plastic strain at its centre's
        reference row; all ones without ``fade``.
        """
        fade = self.options["fade"]
        peak = self.model.plastic_strain + self.model.neck_strain
        if self._fade_rates is None or peak <= 0.0:
            return self._unfaded
        damage = self.model.plastic_strain_yy(i, self._ys) / peak
        return np.maximum(1.0 - fade * self._fade_rates * damage, 0.0)

    def _clean(self, i: int) -> np.ndarray:
        if self.lens is not None:
            return self._render_through_lens(i, self.lens)
        full = float(self.full_scale)
        Y, alpha, beta = self.model.inverse_rows(i, self._rows)
        hw = self.model.half_width(Y)
        # Deformed columns of the specimen edges on each row (X = xc -+ hw).
        left = (self.model.x_centre - hw - alpha) / beta
        right = (self.model.x_centre + hw - alpha) / beta
        row_cover = self.model.row_cover(i, self._rows)
        image = np.empty(self.shape, dtype=np.float32)
        render_specimen(self._xs, self._ys, self.fade_amplitudes(i), float(self.pattern.radius),
                         float(self.pattern.cutoff_px), Y, alpha, beta, left, right, row_cover,
                         full * self._background, full, PAINT_FLOOR, PAINT_GAIN, image)
        return image


    def _render_through_lens(self, i: int, lens: Lens) -> np.ndarray:
        """The frame as a distorting lens shows it: every pixel's ideal position (x_u, y_u) inverted
        through the model (``inverse_rows`` at y_u, then the row's column map at x_u) and the speckle
        summed there exactly (``SpecklePattern.intensity``, each spot faded as ``fade_amplitudes`` says, as
        the row renderer fades it); the specimen's edges and the crack blended as
        ``render_specimen`` does, measured in ideal pixels (equal to image pixels to within the lens's
        local scale, 1 - 3 k1 r^2 at most)."""
        full = float(self.full_scale)
        ideal = lens.ideal_pixels()
        xu, yu = ideal[..., 0], ideal[..., 1]
        Y, alpha, beta = self.model.inverse_rows(i, yu.ravel())
        Y, alpha, beta = Y.reshape(yu.shape), alpha.reshape(yu.shape), beta.reshape(yu.shape)
        X = alpha + beta * xu
        hw = self.model.half_width(Y)
        left = (self.model.x_centre - hw - alpha) / beta
        right = (self.model.x_centre + hw - alpha) / beta
        cover = np.clip(np.minimum(xu - left, right - xu) + 0.5, 0.0, 1.0)
        cover *= self.model.row_cover(i, yu.ravel()).reshape(yu.shape)
        image = np.repeat((full * self._background)[:, None], self.shape[1], axis=1).astype(np.float64)
        inside = cover > 0.0
        painted = paint(self.pattern.intensity(X[inside], Y[inside], self.fade_amplitudes(i)), full)
        image[inside] += cover[inside] * (painted - image[inside])
        return image.astype(np.float32)


class SyntheticTranslateSource(_PrerenderedSource):
    """Speckle over the whole image, shifted by ``(du, dv)`` px per frame plus an optional jump.

    ``truth(i, x, y)`` is the same (u, v) for every point: ``(i du, i dv)``, plus
    ``(U, V)`` from frame F on when ``jump=F:U:V``.
    """

    model_name = "translate"

    def __init__(self, uri: str = "synthetic:translate", **options: Any) -> None:
        model, raw = parse_synthetic_uri(uri)
        if model != "translate":
            raise SourceError(f"{uri!r} is not a translate URI: use synthetic:translate?...")
        raw.update({k: v for k, v in options.items() if v is not None})
        opts = convert_options("translate", raw)
        self._opts_for_margin = opts
        super().__init__(opts, uri)

    def _pattern_margin(self) -> int:
        opts = self._opts_for_margin
        n = rendered_count(opts) - 1
        extent = max(abs(opts["du"]), abs(opts["dv"])) * n
        if opts["jump"] is not None:
            extent += max(abs(opts["jump"][1]), abs(opts["jump"][2]))
        reach = 5.0 * opts["radius"]
        lens = lens_from_options(opts)
        if lens is not None:
            # the lens moves the image's border by up to this much (barrel: inward, so the scene reaches further)
            width, height = opts["size"]
            border = np.array([[0.0, 0.0], [width - 1.0, 0.0], [0.0, height - 1.0], [width - 1.0, height - 1.0],
                               [(width - 1) / 2.0, 0.0], [0.0, (height - 1) / 2.0]])
            extent += float(np.max(np.abs(lens.undistort(border) - border)))
        return math.ceil(reach) + 16 + math.ceil(extent)

    def shift(self, frame_index: int) -> tuple[float, float]:
        """(u, v) of every point in frame ``frame_index``."""
        u = frame_index * self.options["du"]
        v = frame_index * self.options["dv"]
        jump = self.options["jump"]
        if jump is not None and frame_index >= jump[0]:
            u += jump[1]
            v += jump[2]
        return u, v

    def _scene_truth(self, frame_index: int, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        u, v = self.shift(self._check_index(frame_index))
        return np.full(x.shape, u), np.full(y.shape, v)

    @property
    def suggested_roi(self) -> tuple[int, int, int, int]:
        H, W = self.shape
        margin = 32
        return (margin, margin, W - 2 * margin, H - 2 * margin)

    def _clean(self, i: int) -> np.ndarray:
        from livedic.dic.speckle import render
        u, v = self.shift(i)
        lens = self.lens
        if lens is None:
            intensity = render(self.pattern, (u, v) if (u or v) else None, bit_depth=None)
        else:
            # pixel x shows the scene point at undistort(x) - (u, v): the speckle summed there exactly
            ideal = lens.ideal_pixels()
            intensity = self.pattern.intensity(ideal[..., 0] - u, ideal[..., 1] - v)
        image = paint(intensity, float(self.full_scale)).astype(np.float32)
        return image


def open_synthetic(uri: str, **options: Any) -> SyntheticTensileSource | SyntheticTranslateSource:
    """The source named by ``uri``: ``synthetic:``, ``synthetic:tensile?...`` or ``synthetic:translate?...``."""
    model, _ = parse_synthetic_uri(uri)
    if model == "translate":
        return SyntheticTranslateSource(uri, **options)
    return SyntheticTensileSource(uri, **options)
