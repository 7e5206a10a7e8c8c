"""``livedic preview``: the set-up of a test, drawn before it starts.

``livedic preview --source URI [placement options] -o PREVIEW.png`` takes the
source's first frame and places the points, P0 and the extensometers exactly as
``livedic run`` would with the same options (``stream.session.points.place_points``,
``StrainConfig.place``), then draws them, labelled, over the frame, beside a map
of what DIC needs from the image: the speckle contrast per subset (mean intensity
gradient), clipped pixels, and the figures of ``dic.region.pattern_quality`` (speckle
size, focus, predicted noise), with advice where something is off.

``setup_overlay`` gathers what is drawn (``SetupOverlay``); ``render_preview``
draws it with matplotlib into the PNG; ``livedic run`` hands the same overlay to
the Rerun view at the start of a session (``RerunLogger.log_setup``). The command itself is
``stream.cli.preview``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np

from livedic.dic.region.pattern_quality import PatternQuality, pattern_quality
from livedic.dic.region import Circle, Polygon, Rectangle, find_specimen, straddling
from livedic.stream.session.points import Placement, PlacedBy

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure, SubFigure

    from livedic.dic.region import Shape
    from livedic.dic.strain.extensometer import Extensometer
    from livedic.stream.stages.strain import StrainStage

__all__ = ["SetupOverlay", "setup_overlay", "region_outlines", "shape_outline", "render_preview"]

# Colours (RGB 0-255) shared by the PNG and the Rerun view.
REGION_COLOUR = (255, 200, 0)
EXCLUDED_COLOUR = (230, 40, 40)
POINT_COLOUR = (40, 200, 60)
WEAK_POINT_COLOUR = (255, 140, 0)
P0_COLOUR = (255, 60, 255)
EXTENSOMETER_COLOURS = ((0, 200, 255), (255, 90, 200), (120, 255, 120), (255, 255, 90))
CLIPPED_COLOUR = (255, 0, 0)
MIG_COLOURMAP = "viridis"


@dataclass(frozen=True)
class SetupOverlay:
    """What a preview draws, computed once for the PNG and the live view (with the palette both draw in).

    Attributes
    ----------
    image : ndarray (H, W)
        The reference frame.
    placement : stream.session.points.Placement
    extensometers : tuple of dic.strain.extensometer.Extensometer
        As placed, ends in reference image px (where they are drawn).
    scale : float or None
        px per mm (``--scale``), for the labels.
    quality : dic.region.pattern_quality.PatternQuality
    outlines : list of ndarray (K, 2)
        Closed polylines (x, y) around the region where subsets may lie (holes included).
    exclusions : list of ndarray (K, 2)
        Closed polylines of the ``--exclude`` shapes.
    weak : ndarray (N,) of bool
        Points whose subset has little contrast (``PatternQuality.weak_subsets``).
    straddle : ndarray (N,) of bool
        Points whose subset lies across the edge of the speckled specimen found in the image
        (``dic.region.straddling``; none when the points were placed on it).
    subset : int
    source : str
    pixel_format : str
        The frame's ("Mono8", "Mono12", "Mono16"), for display.
    extensometer_warnings : tuple of str
        The strain stage's (``StrainStage.noise_warnings``: too short for its noise).
    l0_px : dict of str to float
        Each extensometer's L0 as the strain stage measures it (undistorted with a calibration), for the
        labels; an extensometer not in it is labelled with its drawn length.
    """
    image: np.ndarray = field(repr=False)
    placement: Placement
    extensometers: tuple[Extensometer, ...]
    scale: float | None
    quality: PatternQuality
    outlines: list[np.ndarray] = field(repr=False)
    exclusions: list[np.ndarray] = field(repr=False)
    weak: np.ndarray = field(repr=False)
    straddle: np.ndarray = field(repr=False)
    subset: int
    source: str
    pixel_format: str = "Mono8"
    extensometer_warnings: tuple[str, ...] = ()
    l0_px: dict[str, float] = field(default_factory=dict)

    REGION_COLOUR = REGION_COLOUR
    EXCLUDED_COLOUR = EXCLUDED_COLOUR
    POINT_COLOUR = POINT_COLOUR
    WEAK_POINT_COLOUR = WEAK_POINT_COLOUR
    P0_COLOUR = P0_COLOUR
    EXTENSOMETER_COLOURS = EXTENSOMETER_COLOURS
    CLIPPED_COLOUR = CLIPPED_COLOUR

    @property
    def region_label(self) -> str:
        return {PlacedBy.SPECIMEN: "specimen (found)", PlacedBy.SOURCE: "ROI (source)",
                PlacedBy.WHOLE_IMAGE: "whole image", PlacedBy.POINTS: "given points"}.get(
            self.placement.placed_by, "mask" if self.placement.spec.mask is not None and
            self.placement.spec.outline is None else "ROI")

    def extensometer_label(self, extensometer: Extensometer) -> str:
        l0 = self.l0_px.get(extensometer.name, extensometer.length_px)
        length = f"L0 {l0:.0f} px"
        if self.scale:
            length += f" ({l0 / self.scale:.2f} mm)"
        return f"{extensometer.name} {length}"

    def lines(self) -> list[str]:
        """The text under the pictures: what was placed, how, and the pattern's figures."""
        placement = self.placement
        weak = int(self.weak.sum())
        lines = [f"{placement.describe()}; subset {self.subset} px"
                 + (f"; {weak} on weak contrast (orange)" if weak else ""),
                 placement.p0.describe()]
        lines += [f"extensometer {self.extensometer_label(e)}: ({e.x1:.0f}, {e.y1:.0f}) - ({e.x2:.0f}, {e.y2:.0f})"
                  for e in self.extensometers]
        lines += self.quality.describe()
        return lines

    def advice(self) -> list[str]:
        """Problems worth fixing before the test (empty when none was found): the set-up's ``checks``, P0's
        warning and the extensometers' (too short for their noise), as ``livedic run`` says them."""
        p0 = self.placement.p0.warning() if self.placement.p0 is not None else None
        return self.checks() + list(self.extensometer_warnings) + ([p0] if p0 else [])

    def checks(self) -> list[str]:
        """What only the set-up looks at: the pattern, exposure and focus, weak subsets, points across the
        specimen's edge (``livedic run`` says P0's and the extensometers' warnings on their own)."""
        advice = list(self.quality.advice())
        if len(self.weak) and self.weak.mean() > 0.05:
            advice.append(f"{int(self.weak.sum())} of {len(self.weak)} points have little speckle contrast in their "
                          f"subset: check the paint there, or leave that area out (--exclude, --mask)")
        if self.straddle.any():
            advice.append(f"{int(self.straddle.sum())} points have their subset across the specimen's edge (part "
                          f"speckle, part background or hole, red in the preview): such a subset sees two motions "
                          f"and can be ok yet wrong; leave --roi out (the specimen is found) or --exclude them")
        return advice


def shape_outline(shape: Shape) -> np.ndarray:
    """A closed polyline (K, 2) of a ``dic.region`` shape, in image px."""
    if isinstance(shape, Circle):
        angles = np.linspace(0.0, 2.0 * np.pi, 65)
        return np.column_stack([shape.x + shape.r * np.cos(angles), shape.y + shape.r * np.sin(angles)])
    if isinstance(shape, Rectangle):
        x0, y0, x1, y1 = shape.bounds
        return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1], [x0, y0]], dtype=np.float64)
    if isinstance(shape, Polygon):
        vertices = np.array(shape.vertices, dtype=np.float64)
        return np.vstack([vertices, vertices[:1]])
    raise TypeError(f"not a region shape: {shape!r}")


def region_outlines(mask: np.ndarray, *, tolerance_px: float = 1.0) -> list[np.ndarray]:
    """Closed polylines (x, y) along the boundary of ``mask`` (outer edges and holes), simplified."""
    import cv2
    contours, _ = cv2.findContours(np.ascontiguousarray(mask, dtype=np.uint8), cv2.RETR_CCOMP,
                                   cv2.CHAIN_APPROX_SIMPLE)
    outlines = []
    for contour in contours:
        simple = cv2.approxPolyDP(contour, tolerance_px, True).reshape(-1, 2).astype(np.float64)
        if len(simple) >= 2:
            outlines.append(np.vstack([simple, simple[:1]]))
    return outlines


def setup_overlay(image: np.ndarray, placement: Placement, strain_stage: StrainStage | None = None, *, subset: int,
                  scale: float | None = None,
                  source: str = "", bit_depth: int | None = None, pixel_format: str = "Mono8") -> SetupOverlay:
    """What to draw for ``placement`` on ``image`` (the reference frame) and the session's strain stage.

    The pattern's figures are taken over the region's speckled part: a given region may hold background,
    a hole or the specimen's edge, which are no pattern (the speckle size over Sample 12's whole image
    came out 50 px, its speckles' 2.4).
    """
    straddle = np.zeros(len(placement.points), dtype=bool)
    measured = placement.region
    # a region given (not the source's, the simulator's gauge section): does it reach off the specimen?
    if placement.placed_by not in (PlacedBy.SPECIMEN, PlacedBy.SOURCE):
        specimen = find_specimen(image, subset)
        if specimen.separated:
            straddle = straddling(placement.points, specimen.mask, subset)
            if (measured & specimen.mask).any():
                measured = measured & specimen.mask
    quality = pattern_quality(image, subset, measured if measured.any() else None, bit_depth=bit_depth)
    extensometers = strain_stage.image_extensometers if strain_stage is not None else ()
    exclusions = [shape_outline(shape) for shape in placement.spec.exclude]
    return SetupOverlay(image=image, placement=placement, extensometers=extensometers, scale=scale,
                        quality=quality, outlines=region_outlines(placement.region), exclusions=exclusions,
                        weak=quality.weak_subsets(placement.points), straddle=straddle, subset=int(subset),
                        source=source, pixel_format=pixel_format,
                        extensometer_warnings=tuple(strain_stage.noise_warnings()) if strain_stage is not None else (),
                        l0_px={e.name: e.length_px for e in strain_stage.extensometers} if strain_stage is not None
                        else {})


# ----------------------------------------------------------------------------- the PNG

def _display(image: np.ndarray) -> np.ndarray:
    """Grey levels 0..1 for display: 8 bit as is, deeper images stretched over their 0.1-99.9 percentiles."""
    f = np.asarray(image, dtype=np.float64)
    if image.dtype == np.uint8:
        return f / 255.0
    lo, hi = np.percentile(f[::4, ::4], [0.1, 99.9])
    return np.clip((f - lo) / max(hi - lo, 1e-9), 0.0, 1.0)


def _rgb(colour: tuple[int, int, int]) -> tuple[float, float, float]:
    red, green, blue = colour
    return red / 255.0, green / 255.0, blue / 255.0


def _label_place(x: Sequence[float], y: Sequence[float], dx: float, dy: float, width: int,
                 height: int) -> tuple[tuple[float, float], tuple[int, int], str, str]:
    """(anchor, offset in points, ha, va) for a line's label: at its top end when it runs along y, its right
    end when along x, set off to the side; flipped back inside the image near an edge."""
    if abs(dy) >= abs(dx):                        # along y: the upper end, text to its right
        anchor = (x[0], y[0]) if y[0] <= y[1] else (x[1], y[1])
        offset, ha, va = (8, 4), "left", "bottom"
        if anchor[0] > 0.7 * width:
            offset, ha = (-8, 4), "right"
    else:                                         # along x: under the right end, the text running back along it
        anchor = (x[0], y[0]) if x[0] >= x[1] else (x[1], y[1])
        offset, ha, va = (0, -8), "right", "top"
    if anchor[1] < 0.05 * height:
        offset, va = (offset[0], -abs(offset[1]) - 6), "top"
    return anchor, offset, ha, va


@dataclass
class _PreviewFigure:
    """The preview's figure: a row of the three pictures over a row of notes."""
    figure: Figure
    pictures: SubFigure
    setup: Axes
    quality: Axes
    focus: Axes
    text: Axes


def render_preview(overlay: SetupOverlay, path: str) -> None:
    """Draw ``overlay`` into the PNG ``path`` (written whole or not at all): set-up | speckle contrast, notes under."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    image = _display(overlay.image)
    advice = overlay.advice()
    notes, checks = _notes(overlay, advice)
    text_lines = notes.count("\n") + checks.count("\n") + 2
    layout = _preview_figure(image.shape, text_lines)
    try:
        _draw_setup(layout.setup, overlay, image)
        _draw_contrast(layout.quality, layout.pictures, overlay, image)
        _draw_focus(layout.focus, layout.pictures, overlay, image)
        height, width = image.shape
        for axes in (layout.setup, layout.quality, layout.focus):
            axes.set_xlim(-0.5, width - 0.5)
            axes.set_ylim(height - 0.5, -0.5)
            axes.tick_params(labelsize=7)
        layout.pictures.suptitle(f"livedic preview: {overlay.source}", fontsize=11)
        _write_notes(layout.text, notes, checks, warned=bool(advice), text_lines=text_lines)
        _save_png(layout.figure, path)
    finally:
        plt.close(layout.figure)


def _notes(overlay: SetupOverlay, advice: list[str]) -> tuple[str, str]:
    """The text under the pictures: the notes (``SetupOverlay.lines``) and the checks of ``advice`` (or that none
    is needed)."""
    import textwrap
    notes = "\n".join(textwrap.fill(line, 150, subsequent_indent="    ") for line in overlay.lines())
    checks = "\n".join(textwrap.fill("check: " + line, 150, subsequent_indent="    ")
                       for line in advice) or "nothing to check: pattern, exposure and focus look fit for DIC"
    return notes, checks


def _preview_figure(shape: tuple[int, ...], text_lines: int) -> _PreviewFigure:
    """The figure for an image of ``shape``: a coupon standing up gets its three pictures side by side, a wide
    field one above the other; the notes row is as tall as ``text_lines``."""
    import matplotlib.pyplot as plt
    height, width = shape
    notes_h = 0.17 * text_lines
    if height >= 0.75 * width:                    # a coupon standing up: the three pictures side by side
        panel_h = min(8.0, max(4.0, 6.5 * height / width))
        panel_w = panel_h * width / height
        size = (max(3 * panel_w + 3.4, 12.0), panel_h + 0.9 + notes_h)
        ratios, grid, widths = [panel_h + 0.6, notes_h + 0.3], (1, 3), {"width_ratios": [1.0, 1.15, 1.15]}
    else:                                         # a wide field: one above the other
        panel_w = 11.0
        panel_h = min(4.0, panel_w * height / width)
        size = (panel_w + 1.5, 3 * panel_h + 1.7 + notes_h)
        ratios, grid, widths = [3 * panel_h + 1.4, notes_h + 0.3], (3, 1), {}
    figure = plt.figure(figsize=size, dpi=110, layout="constrained")
    # subfigures(2, 1) is an array of the two rows
    pictures, below = cast("np.ndarray", figure.subfigures(2, 1, height_ratios=ratios))
    setup_axes, quality_axes, focus_axes = pictures.subplots(*grid, **widths)
    return _PreviewFigure(figure, pictures, setup_axes, quality_axes, focus_axes, below.add_subplot())


def _draw_setup(axes: Axes, overlay: SetupOverlay, image: np.ndarray) -> None:
    """The set-up: the region (outside it greyed), exclusions, points, P0 and its subset, extensometers."""
    import matplotlib.patheffects as effects
    import matplotlib.pyplot as plt
    height, width = image.shape
    halo = [effects.withStroke(linewidth=2.5, foreground="black")]
    axes.imshow(image, cmap="gray", vmin=0, vmax=1, interpolation="antialiased")
    axes.imshow(np.ma.masked_where(overlay.placement.region, np.ones(image.shape)), cmap="gray_r", vmin=0, vmax=1,
                alpha=0.5, interpolation="nearest")
    for k, outline in enumerate(overlay.outlines):
        axes.plot(outline[:, 0], outline[:, 1], color=_rgb(REGION_COLOUR), linewidth=1.2,
                  label=overlay.region_label if k == 0 else None)
    for k, outline in enumerate(overlay.exclusions):
        axes.fill(outline[:, 0], outline[:, 1], facecolor=(*_rgb(EXCLUDED_COLOUR), 0.3),
                  edgecolor=_rgb(EXCLUDED_COLOUR), hatch="///", linewidth=1.2, label="excluded" if k == 0 else None)
    points = overlay.placement.points
    dot = float(np.clip(6000.0 / max(len(points), 1), 1.5, 12.0))
    good = ~overlay.weak
    axes.scatter(points[good, 0], points[good, 1], s=dot, color=_rgb(POINT_COLOUR), linewidths=0,
                 label=f"{len(points)} points (every {overlay.placement.step} px)"
                 if overlay.placement.step else f"{len(points)} points")
    if overlay.weak.any():
        axes.scatter(points[~good, 0], points[~good, 1], s=2 * dot, color=_rgb(WEAK_POINT_COLOUR),
                     linewidths=0, label=f"{int(overlay.weak.sum())} on weak contrast")
    if overlay.straddle.any():
        across = overlay.straddle
        axes.scatter(points[across, 0], points[across, 1], s=3 * dot, facecolors="none",
                     edgecolors=_rgb(EXCLUDED_COLOUR), linewidths=0.8,
                     label=f"{int(across.sum())} across the specimen's edge")
    p0x, p0y = points[0]
    half = overlay.subset / 2.0
    axes.add_patch(plt.Rectangle((p0x - half, p0y - half), overlay.subset, overlay.subset, fill=False,
                                 edgecolor=_rgb(P0_COLOUR), linewidth=1.5,
                                 label=f"P0 and its {overlay.subset} px subset"))
    axes.plot([p0x], [p0y], marker="+", markersize=10, color=_rgb(P0_COLOUR), mew=2)
    axes.annotate("P0", (p0x - half, p0y - half), xytext=(-4, 4), textcoords="offset points",
                  color=_rgb(P0_COLOUR), fontsize=9, fontweight="bold", ha="right", va="bottom", path_effects=halo)
    for k, extensometer in enumerate(overlay.extensometers):
        colour = _rgb(EXTENSOMETER_COLOURS[k % len(EXTENSOMETER_COLOURS)])
        xs, ys = (extensometer.x1, extensometer.x2), (extensometer.y1, extensometer.y2)
        axes.plot(xs, ys, color=colour, linewidth=2, marker="o", markersize=4)
        anchor, offset, ha, va = _label_place(xs, ys, xs[1] - xs[0], ys[1] - ys[0], width, height)
        axes.annotate(overlay.extensometer_label(extensometer).replace(" L0 ", "\nL0 ", 1), anchor, xytext=offset,
                      textcoords="offset points", color=colour, fontsize=9, fontweight="bold", ha=ha, va=va,
                      path_effects=halo)
    axes.set_title("set-up", fontsize=10)
    axes.legend(loc="lower left", fontsize=7, framealpha=0.85, markerscale=2)


def _draw_contrast(axes: Axes, bar_row: SubFigure, overlay: SetupOverlay, image: np.ndarray) -> None:
    """What DIC needs: the speckle contrast (MIG) per subset over the region, clipped pixels on it in red."""
    import matplotlib
    region, quality = overlay.placement.region, overlay.quality
    axes.imshow(image, cmap="gray", vmin=0, vmax=1, interpolation="antialiased")
    top = float(np.percentile(quality.mig[region], 99)) if region.any() else 1.0
    shown = axes.imshow(np.ma.masked_where(~region, quality.mig), cmap=MIG_COLOURMAP, vmin=0.0,
                        vmax=max(top, 1e-6), alpha=0.9, interpolation="nearest")
    clipped = quality.clipped & region
    if clipped.any():
        axes.imshow(np.ma.masked_where(~clipped, np.ones(image.shape)),
                    cmap=matplotlib.colors.ListedColormap([_rgb(CLIPPED_COLOUR)]), vmin=0, vmax=1,
                    interpolation="nearest")
    bar = bar_row.colorbar(shown, ax=axes, fraction=0.06, pad=0.02, shrink=0.9)
    bar.set_label(f"MIG over a {overlay.subset} px subset (grey levels/px)", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    axes.set_title(f"speckle contrast: MIG median {quality.mig_median:.1f}; clipped pixels in red "
                   f"({100 * quality.clipped_share:.2f} %)", fontsize=10)


def _draw_focus(axes: Axes, bar_row: SubFigure, overlay: SetupOverlay, image: np.ndarray) -> None:
    """Focus: the sharpness per subset against the specimen's median (defocus takes the fine detail first)."""
    region, quality = overlay.placement.region, overlay.quality
    sharp = quality.sharpness
    median = float(np.nanmedian(sharp[region])) if region.any() else float("nan")
    relative = np.ma.masked_where(~region | ~np.isfinite(sharp), sharp / median if median > 0 else sharp)
    axes.imshow(image, cmap="gray", vmin=0, vmax=1, interpolation="antialiased")
    focus = axes.imshow(relative, cmap="RdYlGn", vmin=0.5, vmax=1.5, alpha=0.9, interpolation="nearest")
    bar = bar_row.colorbar(focus, ax=axes, fraction=0.06, pad=0.02, shrink=0.9)
    bar.set_label("sharpness (|Laplacian| / |gradient|) over the specimen's median", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    spread = quality.sharpness_spread
    axes.set_title("focus: " + ("n/a" if not math.isfinite(spread) else
                                f"spread {spread:.2f}x across the specimen (1 = even)"), fontsize=10)


def _write_notes(axes: Axes, notes: str, checks: str, *, warned: bool, text_lines: int) -> None:
    """The notes, and under them the checks (red-brown when there is something to check, green when not)."""
    axes.axis("off")
    axes.text(0.0, 1.0, notes, fontsize=8, va="top", ha="left", family="monospace", transform=axes.transAxes,
              linespacing=1.35)
    below = (notes.count("\n") + 1) / text_lines
    axes.text(0.0, 1.0 - below, checks, fontsize=8, va="top", ha="left", family="monospace",
              transform=axes.transAxes, linespacing=1.35, color="#b03000" if warned else "#207020")


def _save_png(figure: Figure, path: str) -> None:
    """``figure`` as the PNG ``path``, written whole or not at all."""
    from livedic.acquire.atomic_file import AtomicFile
    with AtomicFile(path, binary=True) as out:
        figure.savefig(out.handle, format="png")
        out.commit()
