"""The simulated tensile test to fracture (issue 12): large strain, fading paint, the coupon breaking.

The default test must render the frames it always rendered (recordings and tests rely on them),
so its images are compared with hashes taken from the code before these options existed.
"""

import hashlib

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.render import _render_rows
from livedic.acquire.simulator.sources import SyntheticTensileSource, open_synthetic
from livedic.dic import measure

LARGE = "synthetic:tensile?strain=0.30&neck=1.0"


def _zncc(a, b):
    a = a - a.mean()
    b = b - b.mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def _row_of(model, frame, Y):
    """Deformed row (nearest pixel) of reference row Y at the coupon's centre line."""
    _, v = model.displacement(frame, model.x_centre, Y)
    return int(round(Y + float(v)))


# --------------------------------------------------------------------------- the default is unchanged

# sha256 of the frames' bytes (in order) rendered by the code before issue 12 (commit 5c55082).
# Images are rounded to integers, so another CPU's last-bit rounding of exp/tanh could only flip a
# pixel lying within ~1e-12 grey levels of a rounding boundary.
BEFORE = [
    ("synthetic:tensile?frames=20&size=160x192&pace=0", None,
     "de632e16bbbaeafea1d89bf723ca6ef81d2b7fb9b8f424881d021ef82a168b08"),
    # Beyond the default strains the small-strain model is the explicit lateral=linear&view=grip.
    ("synthetic:tensile?frames=12&size=128x160&bit=12&noise=0.5&seed=3&strain=0.1&neck=0.3&radius=3&pace=0"
     "&lateral=linear&view=grip", None, "4acebe0d68783feefb3226d7ef502f8932b1e5cfdc65484a9dd721f43045b721"),
    ("synthetic:tensile?frames=9&loop=5&size=96x128&pace=0", None,
     "8c7f37ed167dbc824a747f8e1ffaa0b61ccaf43142f0342716d71f2cbd935e13"),
    ("synthetic:tensile?pace=0", (0, 1, 150, 200, 299),             # the main job's source, 1 MP
     "8462de5a8c2018132c631fb97af2bb970659df6df3b7c17804feedce61282cba"),
]


@pytest.mark.parametrize("uri, frames, digest", BEFORE)
def test_default_frames_are_bit_for_bit_those_before_the_new_options(uri, frames, digest):
    source = SyntheticTensileSource(uri)
    h = hashlib.sha256()
    for i in range(source.rendered_frames) if frames is None else frames:
        h.update(source._render(i).tobytes())
    assert h.hexdigest() == digest


def test_default_truth_is_that_before_the_new_options():
    """Exact displacements of the default 1 MP test, as the code before issue 12 gave them."""
    source = SyntheticTensileSource("synthetic:tensile?pace=0")
    x = np.array([300.0, 512.0, 700.0, 420.5])
    y = np.array([200.0, 450.0, 839.0, 600.25])
    before = {
        150: ([3.0608118739149717, -0.03872406983796732, -2.0070262549558042, 1.8882129071041487],
              [-27.626087574575696, -17.11210551459839, -0.8489613056509219, -10.640134245125578],
              0.04152852653809635),
        299: ([3.9154732621876365, -0.004799869323716802, -2.3471996152031336, 2.873271727626139],
              [-55.373005192755976, -31.745539656018202, -0.8359579930655282, -13.241346208067062],
              0.08404507725102096),
    }
    for i, (u, v, nominal) in before.items():
        tu, tv = source.truth(i, x, y)
        np.testing.assert_allclose(tu, u, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(tv, v, rtol=1e-13, atol=1e-12)
        assert source.frame_metadata(i)["nominal_strain"] == pytest.approx(nominal, rel=1e-13)
    settings = source.settings
    assert (settings["lateral"], settings["view"], settings["fade"], settings["fracture"]) == \
        ("linear", "grip", 0.0, 0)
    assert source.fracture_frame is None and "fracture_frame" not in source.frame_metadata(299)


# --------------------------------------------------------------------------- large strain, exact

@pytest.mark.parametrize("uri, frame", [
    (LARGE + "&frames=20&size=160x192&pace=0", 19),                       # deepest neck, 130 % peak
    (LARGE + "&frames=20&size=160x192&pace=0&fracture=1&fade=0.5", 19),   # broken, faded
    (LARGE + "&frames=20&size=160x192&pace=0&view=grip", 19),
])
def test_large_strain_rows_are_exact_inverses_and_the_kernel_is_the_pattern(uri, frame):
    """Every covered pixel (c, r) is the image of the reference point the row inverse finds: the forward
    truth maps it back onto (c, r) to 1e-9 px; the kernel there equals dic.speckle's Zhou-Goodson sum,
    and the rendered (noise-free) frame is the paint of that sum, faded as documented."""
    source = SyntheticTensileSource(uri + "&noise=0")
    model = source.model
    height, width = source.shape
    rows = np.arange(height, dtype=float)
    Y, alpha, beta = model.inverse_rows(frame, rows)
    covered = model.row_cover(frame, rows) == 1.0
    X = alpha[:, None] + beta[:, None] * np.arange(width)[None, :]
    YY = np.broadcast_to(Y[:, None], X.shape)
    U, V = model.displacement(frame, X, YY)
    np.testing.assert_allclose((X + U)[covered], np.broadcast_to(np.arange(width, dtype=float), X.shape)[covered],
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose((YY + V)[covered], np.broadcast_to(rows[:, None], X.shape)[covered], rtol=0,
                               atol=1e-9)
    out = np.zeros((height, width))
    centres = source.pattern.centres
    _render_rows(np.ascontiguousarray(centres[:, 0]), np.ascontiguousarray(centres[:, 1]), source.pattern.radius,
                 source.pattern.cutoff_px, Y, alpha, beta, np.zeros(height, np.int64), np.full(height, width, np.int64),
                 out)
    np.testing.assert_allclose(out, source.pattern.intensity(X, YY), rtol=0, atol=1e-9)
    # The frame itself, well inside the coupon (coverage 1): the paint of the faded sum at those points.
    image = source._render(frame).astype(float)
    amp = source.fade_amplitudes(frame)
    xs, ys = centres[:, 0], centres[:, 1]
    full = source.full_scale
    for r in np.flatnonzero(covered)[::7]:
        hw = model.half_width(Y[r])
        inside = np.flatnonzero(np.abs(X[r] - model.x_centre) < hw - 2 * beta[r])[::5]
        for c in inside:
            d2 = (xs - X[r, c]) ** 2 + (ys - Y[r]) ** 2
            near = d2 < source.pattern.cutoff_px ** 2
            intensity = np.sum(amp[near] * np.exp(-d2[near] / source.pattern.radius ** 2))
            expected = full * (0.06 + 0.88 * np.exp(-intensity))
            assert abs(image[r, c] - expected) <= 0.5 + 1e-3


def test_large_strain_truth_agrees_with_icgn_and_flow_keeps_the_volume():
    """30 % uniform plastic strain (end of the uniform phase): IC-GN from frame 0 finds the truth within
    0.01 px where the field is affine over a subset, and the measured gradients show incompressible flow:
    (1 + du/dx)^2 (1 + dv/dy) = 1 within 0.005 (the elastic part's 0.4 e_el = 0.0016 and noise), where
    the linear law would give 0.94."""
    source = SyntheticTensileSource(LARGE + "&frames=41&size=384x384&noise=0&pace=0")
    assert source.settings["lateral"] == "incompressible" and source.settings["view"] == "centre"
    model = source.model
    frames = _frames(source)
    x0, _, w, _ = source.suggested_roi
    xs = np.linspace(x0 + 15, x0 + w - 16, 4)
    ys = np.linspace(model.gauge_top + 50, model.gauge_bottom - 50, 5)
    points = np.array([(x, y) for x in xs for y in ys])
    index = 24                                          # tau = 0.6: 30 % uniform, no neck yet
    assert model.state(index)["e_pl"] == pytest.approx(0.30)
    tu, tv = source.truth(index, points[:, 0], points[:, 1])
    m = measure(frames[0].image, frames[index].image, points, search="exhaustive", subpixel="icgn", radius=4,
                guess=np.column_stack([np.round(tu), np.round(tv)]), subpixel_options={"max_iterations": 50})
    assert m.ok.all()
    mu, mv = frames[index].metadata["truth"](m.x, m.y)
    assert np.max(np.hypot(m.u - mu, m.v - mv)) < 0.01
    volume = (1.0 + m.ux) ** 2 * (1.0 + m.vy)
    np.testing.assert_allclose(volume, 1.0, atol=0.005)
    assert np.ptp(tv) > 40.0                            # a real stretch (the camera keeps the centre put)


def test_incompressible_law_keeps_the_volume_at_the_deepest_neck():
    """At 130 % peak strain the width's stretch is (1 - 0.3 e_el) / sqrt(1 + e_p): width^2 x length = 1
    within the elastic part (0.4 e_el <= 0.0016) on every gauge row, from the truth itself."""
    source = SyntheticTensileSource(LARGE + "&frames=50&size=256x512&pace=0")
    model = source.model
    Y = np.linspace(model.gauge_top, model.gauge_bottom, 200)
    last = 49
    u_edge, _ = source.truth(last, np.full(Y.shape, model.x_centre + 40.0), Y)
    u_mid, _ = source.truth(last, np.full(Y.shape, model.x_centre), Y)
    width_stretch = (40.0 + u_edge - u_mid) / 40.0
    h = 1e-3
    _, v_up = source.truth(last, np.full(Y.shape, model.x_centre), Y - h)
    _, v_down = source.truth(last, np.full(Y.shape, model.x_centre), Y + h)
    length_stretch = 1.0 + (v_down - v_up) / (2 * h)
    assert length_stretch.max() > 2.29                     # the neck reached 1 + 0.30 + 1.0
    np.testing.assert_allclose(width_stretch ** 2 * length_stretch, 1.0, atol=0.002)
    np.testing.assert_allclose(length_stretch - 1.0, model.strain_yy(last, Y), atol=1e-6)


# --------------------------------------------------------------------------- fading paint

def test_fade_lowers_contrast_only_where_the_paint_strained():
    base = LARGE + "&frames=50&size=256x512&noise=0&pace=0&view=grip"
    plain, faded = SyntheticTensileSource(base), SyntheticTensileSource(base + "&fade=0.5")
    model = plain.model
    # Elastic phase: no plastic strain, nothing fades (bit for bit).
    assert np.array_equal(plain._render(5), faded._render(5))
    last = 49
    a, b = plain._render(last).astype(float), faded._render(last).astype(float)
    c = int(round(model.x_centre))

    def patch(image, Y):
        r = _row_of(model, last, Y)
        return image[r - 10:r + 11, c - 10:c + 11]

    neck_a, neck_b = patch(a, model.y_neck), patch(b, model.y_neck)
    assert neck_b.std() < 0.8 * neck_a.std()               # contrast lost ...
    assert neck_b.mean() > neck_a.mean() + 10              # ... as the dark spots pale
    assert _zncc(neck_a, neck_b) < 0.98                    # the pattern itself changed
    shoulder = 0.94 * model.shape[0]                       # beyond the plastic zone
    assert float(model.plastic_strain_yy(last, shoulder)) < 1e-3
    assert np.max(np.abs(patch(a, shoulder) - patch(b, shoulder))) <= 1.0
    assert _zncc(patch(a, shoulder), patch(b, shoulder)) > 0.9999


# --------------------------------------------------------------------------- fracture

FRACTURE = "synthetic:tensile?frames=30&size=192x256&noise=0&pace=0&fracture=1"


def test_fracture_frame_schedule_and_unloading():
    source = SyntheticTensileSource(FRACTURE)
    model = source.model
    assert source.fracture_frame == 27 == source.settings["fracture"]       # 30 - round(0.1 x 30)
    assert SyntheticTensileSource(FRACTURE.replace("fracture=1", "fracture=20")).fracture_frame == 20
    phases = [source.frame_metadata(i)["phase"] for i in range(30)]
    assert phases[26] == "necking" and phases[27:] == ["fractured"] * 3
    assert all(source.frame_metadata(i)["fracture_frame"] == 27 for i in (0, 27))
    before, broken = model.state(26), model.state(28)
    assert before["e_neck"] == pytest.approx(model.neck_strain)          # the neck is complete when it breaks
    assert broken["e_el"] == 0.0 and broken["e_neck"] == before["e_neck"] and broken["gap"] == 5.0
    assert model.state(27)["gap"] == 3.0
    assert [model.fractured(i) for i in (26, 27)] == [False, True]


def test_fracture_gap_is_background_and_the_halves_move_apart():
    source = SyntheticTensileSource(FRACTURE)
    model = source.model
    full = source.full_scale
    frames = _frames(source)
    for i in (27, 29):
        upper, lower = model.crack_faces(i)
        assert lower - upper == model.state(i)["gap"]
        gap_rows = np.arange(int(np.ceil(upper + 0.5)), int(np.floor(lower - 0.5)) + 1)
        assert gap_rows.size >= model.state(i)["gap"] - 1
        background = np.rint(full * source._background[gap_rows])[:, None]
        gap = frames[i].image[gap_rows].astype(float)
        np.testing.assert_array_equal(gap, np.broadcast_to(background, gap.shape))   # no speckle across the gap
        # Speckle right beside the crack on both faces.
        for r in (int(np.floor(upper - 1.5)), int(np.ceil(lower + 1.5))):
            row = frames[i].image[r, int(model.x_centre) - 20:int(model.x_centre) + 21].astype(float)
            assert row.std() > 5.0
    # Material just above / below the crack: the upper half moved away by the gap (and the unloading).
    x = np.full(2, model.x_centre)
    y = np.array([model.y_neck - 1e-6, model.y_neck])
    for i in (26, 27, 29):
        _, v = source.truth(i, x, y)
        assert v[0] - v[1] == pytest.approx(-model.state(i)["gap"], abs=1e-5)


def test_fracture_truth_is_exact_on_both_halves():
    """IC-GN on the last (broken) frame against frame 0, far from the neck on both halves: the truth within
    0.02 px (the field is affine over those subsets); the upper half has moved up by the gap."""
    source = SyntheticTensileSource(FRACTURE)
    model = source.model
    frames = _frames(source)
    x0, _, w, _ = source.suggested_roi
    xs = np.linspace(x0 + 15, x0 + w - 16, 3)
    ys = [model.gauge_top + 20, model.gauge_top + 30, model.gauge_bottom - 30, model.gauge_bottom - 20]
    points = np.array([(x, y) for x in xs for y in ys])
    last = 29
    assert model.visible(last, points[:, 0], points[:, 1], 10).all()
    tu, tv = source.truth(last, points[:, 0], points[:, 1])
    m = measure(frames[0].image, frames[last].image, points, search="exhaustive", subpixel="icgn", radius=4,
                guess=np.column_stack([np.round(tu), np.round(tv)]), subpixel_options={"max_iterations": 50})
    assert m.ok.all()
    mu, mv = frames[last].metadata["truth"](m.x, m.y)
    assert np.max(np.hypot(m.u - mu, m.v - mv)) < 0.02
    upper = m.y < model.y_neck
    assert upper.any() and (~upper).any()
    assert np.min(m.v[~upper]) - np.max(m.v[upper]) > model.state(last)["gap"]


def test_visible_points_are_those_whose_subset_is_whole_in_the_frame():
    source = SyntheticTensileSource(FRACTURE)
    model = source.model
    x0, y0, w, h = source.suggested_roi
    X, Y = np.meshgrid(np.arange(x0, x0 + w, 4.0), np.arange(y0, y0 + h, 1.0))
    d = 10
    assert source.visible(26, X, Y, d).all()              # before the fracture: all of the gauge ROI
    for i in (27, 29):
        seen = source.visible(i, X, Y, d)
        np.testing.assert_array_equal(seen, (Y - d >= model.y_neck) | (Y + d < model.y_neck))
        assert _subsets_clear_of_the_crack(source, i, X[seen], Y[seen], d)
        assert not _subsets_clear_of_the_crack(source, i, X[~seen], Y[~seen], d)
        # FrameTruth carries the same answer for consumers that only hold the frame.
        np.testing.assert_array_equal(source.frame_metadata(i)["truth"].visible(X, Y, d), seen)
    # A point in the crack band is not visible; with d = 0 only the crack line splits the halves.
    assert not source.visible(27, model.x_centre, model.y_neck + 3, 10)
    assert source.visible(27, model.x_centre, model.y_neck + 3, 0)
    # Off the coupon (background) or off the image: not visible.
    assert not source.visible(0, 5.0, 100.0, 0)
    assert not source.visible(0, model.x_centre, 5.0, 10)


def _subsets_clear_of_the_crack(source, i, X, Y, d):
    """Whether every deformed subset (reference rows Y - d .. Y + d) lies wholly above or below the crack."""
    upper, lower = source.model.crack_faces(i)
    _, v_top = source.truth(i, X, Y - d)
    _, v_bottom = source.truth(i, X, Y + d)
    top, bottom = Y - d + v_top, Y + d + v_bottom
    return bool(np.all((bottom <= upper) | (top >= lower)))


def test_large_strain_carries_points_out_of_view_and_visible_says_so():
    """With the bottom grip fixed in view, 30 % / 100 % carries the top of the gauge out of the image:
    those points are not visible; with view=centre (the default at these strains) the gauge stays in,
    all but its ends (the deformed gauge spans ~97 % of the height)."""
    grip = SyntheticTensileSource(LARGE + "&frames=20&size=192x256&pace=0&view=grip")
    centre = SyntheticTensileSource(LARGE + "&frames=20&size=192x256&pace=0")
    x0, y0, w, h = grip.suggested_roi
    X, Y = np.meshgrid(np.arange(x0, x0 + w, 4.0), np.arange(y0, y0 + h, 2.0))
    _, v = grip.truth(19, X, Y)
    out = Y - 5 + v < 0
    assert out.mean() > 0.1
    seen = grip.visible(19, X, Y, 5)
    assert not seen[out].any() and seen[Y - 5 + v > 1].all()
    assert seen.mean() < 0.9 and centre.visible(19, X, Y, 5).mean() > 0.95   # only the ROI's end rows leave


# --------------------------------------------------------------------------- options

@pytest.mark.parametrize("uri, words", [
    ("synthetic:tensile?fade=2", "option fade='2': must be in 0..1"),
    ("synthetic:tensile?fade=-0.1", "option fade='-0.1': must be >= 0"),
    ("synthetic:tensile?fracture=abc", "option fracture='abc': write 0"),
    ("synthetic:tensile?fracture=300", r"option fracture=300: the frame it breaks at must be in 2\.\.299"),
    ("synthetic:tensile?frames=2&fracture=1", "needs frames >= 3"),
    ("synthetic:tensile?frames=20&loop=5&fracture=1", "cannot be cycled with loop=5"),
    ("synthetic:tensile?lateral=elastic", "option lateral='elastic': choose one of auto, linear, incompressible"),
    ("synthetic:tensile?view=top", "option view='top': choose one of auto, grip, centre"),
    ("synthetic:tensile?lateral=linear&strain=0.8&neck=1.2", "use lateral=incompressible"),
    ("synthetic:translate?fade=0.2", "unknown option"),
])
def test_bad_fracture_options_raise_one_clear_source_error(uri, words):
    with pytest.raises(SourceError, match=words) as error:
        open_synthetic(uri)
    assert "\n" not in str(error.value)


def test_auto_options_resolve_by_the_strains():
    assert SyntheticTensileSource("synthetic:tensile?strain=0.05&neck=0.15").model.lateral == "linear"
    large = SyntheticTensileSource(LARGE + "&fracture=yes&fade=0.2")
    assert (large.model.lateral, large.model.view, large.fracture_frame) == ("incompressible", "centre", 270)
    forced = SyntheticTensileSource(LARGE + "&lateral=linear&view=grip&fracture=0")
    assert (forced.model.lateral, forced.model.view, forced.fracture_frame) == ("linear", "grip", None)


def _frames(source):
    with source:
        return list(source)
