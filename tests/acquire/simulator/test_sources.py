"""The simulated cameras: options, exact rendering, exact truth, the neck, pacing."""

import time

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.simulator.model import TensileModel
from livedic.acquire.simulator.render import _render_rows
from livedic.acquire.simulator.sources import SyntheticTensileSource, SyntheticTranslateSource, open_synthetic
from livedic.dic import measure


def _frames(source):
    with source:
        return list(source)


# --------------------------------------------------------------------------- options

@pytest.mark.parametrize("uri, words", [
    ("synthetic:bend", "unknown synthetic model"),
    ("synthetic:tensile?frams=3", "unknown option"),
    ("synthetic:tensile?frames=1", "frames"),
    ("synthetic:tensile?size=100", "WIDTHxHEIGHT"),
    ("synthetic:tensile?bit=10", "8 or 12"),
    ("synthetic:tensile?fps=0", "fps"),
    ("synthetic:tensile?frames", "no value"),
    ("synthetic:translate?jump=3:1", "FRAME:U:V"),
    ("synthetic:tensile?frames=100000&size=4096x4096", "GiB"),
])
def test_bad_options_raise_one_clear_source_error(uri, words):
    with pytest.raises(SourceError, match=words):
        open_synthetic(uri)


# --------------------------------------------------------------------------- rendering

def test_rows_kernel_equals_the_speckle_pattern_at_inverse_mapped_points():
    """The per-row renderer evaluates exactly dic.speckle's Zhou-Goodson sum (same centres, same cutoff)."""
    source = SyntheticTensileSource("synthetic:tensile?frames=20&size=160x192&pace=0")
    model = source.model
    height, width = source.shape
    Y, alpha, beta = model.inverse_rows(19, np.arange(height, dtype=float))
    X = alpha[:, None] + beta[:, None] * np.arange(width)[None, :]
    YY = np.broadcast_to(Y[:, None], X.shape)
    U, V = model.displacement(19, X, YY)
    np.testing.assert_allclose(X + U, np.broadcast_to(np.arange(width, dtype=float), X.shape), atol=1e-9)
    np.testing.assert_allclose(YY + V, np.broadcast_to(np.arange(height, dtype=float)[:, None], X.shape), atol=1e-9)
    out = np.zeros((height, width))
    centres = source.pattern.centres
    _render_rows(np.ascontiguousarray(centres[:, 0]), np.ascontiguousarray(centres[:, 1]), source.pattern.radius,
                 source.pattern.cutoff_px, Y, alpha, beta, np.zeros(height, np.int64), np.full(height, width, np.int64),
                 out)
    np.testing.assert_allclose(out, source.pattern.intensity(X, YY), rtol=0, atol=1e-9)


def test_frames_formats_timestamps_and_dark_background():
    frames = _frames(SyntheticTensileSource("synthetic:tensile?frames=4&size=128x160&fps=40&pace=0"))
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert [f.timestamp_ns for f in frames] == [0, 25_000_000, 50_000_000, 75_000_000]
    image = frames[0].image
    assert image.dtype == np.uint8 and image.shape == (160, 128) and frames[0].pixel_format == "Mono8"
    # The speckled coupon is bright, the background outside it dark and flat: ROI selection matters.
    assert image[:, :8].mean() < 40 and image[80, 60:68].mean() > 60
    assert callable(frames[2].metadata["truth"]) and frames[2].metadata["phase"] in ("elastic", "plastic", "necking")
    mono12 = _frames(SyntheticTensileSource("synthetic:tensile?frames=2&size=96x96&bit=12&pace=0"))[1]
    assert mono12.image.dtype == np.uint16 and mono12.pixel_format == "Mono12" and mono12.image.max() < 4096
    assert mono12.image.max() > 1000


def test_pacing_delivers_at_the_frame_rate_and_unpaced_is_fast(monkeypatch):
    """Paced: never faster than the frame rate (a lower bound holds on any machine). Unpaced: it never
    waits (counted, not timed: a loaded machine can be slow without the source waiting)."""
    import livedic.acquire.simulator.sources as synthetic
    waits = []
    real_sleep = time.sleep

    def sleep(seconds):
        waits.append(seconds)
        real_sleep(seconds)

    monkeypatch.setattr(synthetic.time, "sleep", sleep)
    source = SyntheticTensileSource("synthetic:tensile?frames=8&size=96x96&fps=40")
    source.prepare()
    start = time.perf_counter()
    _frames(source)
    # the clock starts at the second frame (asked for once the session is ready): 6 periods to the eighth
    assert time.perf_counter() - start >= 6 / 40 - 0.01
    assert waits and sum(waits) <= 6 / 40 + 1e-9       # it waited for the schedule, never beyond it
    waits.clear()
    source = SyntheticTensileSource("synthetic:tensile?frames=8&size=96x96&fps=5&pace=0")
    source.prepare()
    frames = _frames(source)
    assert waits == [] and len(frames) == 8
    assert [f.timestamp_ns for f in frames] == [i * 200_000_000 for i in range(8)]   # still stamped at 5 fps


def test_noise_is_seeded_and_bounded():
    a = _frames(SyntheticTranslateSource("synthetic:translate?frames=2&size=96x96&noise=2&seed=5&pace=0"))
    b = _frames(SyntheticTranslateSource("synthetic:translate?frames=2&size=96x96&noise=2&seed=5&pace=0"))
    c = _frames(SyntheticTranslateSource("synthetic:translate?frames=2&size=96x96&noise=0&seed=5&pace=0"))
    assert np.array_equal(a[1].image, b[1].image)
    diff = a[1].image.astype(float) - c[1].image.astype(float)
    assert 1.5 < diff.std() < 2.5


# --------------------------------------------------------------------------- truth

def test_tensile_truth_is_exact_for_measured_points():
    """IC-GN on a noise-free deformed frame agrees with truth(frame, x, y) to ~0.02 px.

    Points lie where the field is affine over a subset (the uniform gauge, before
    the neck), so the first-order shape function is exact and only the truth is tested.
    """
    source = SyntheticTensileSource("synthetic:tensile?frames=41&size=384x384&noise=0&pace=0")
    frames = _frames(source)
    model = source.model
    x0, _, w, _ = source.suggested_roi
    xs = np.linspace(x0 + 15, x0 + w - 16, 4)
    ys = np.linspace(model.gauge_top + 50, model.gauge_bottom - 50, 5)
    points = np.array([(x, y) for x in xs for y in ys])
    for index in (8, 24):           # late elastic, plastic
        frame = frames[index]
        tu, tv = source.truth(index, points[:, 0], points[:, 1])
        m = measure(frames[0].image, frame.image, points, search="exhaustive", subpixel="icgn", radius=4,
                    guess=np.column_stack([np.round(tu), np.round(tv)]), subpixel_options={"max_iterations": 50})
        assert m.ok.all()
        mu, mv = frame.metadata["truth"](m.x, m.y)
        np.testing.assert_allclose(mu, source.truth(index, m.x, m.y)[0])
        assert np.max(np.hypot(m.u - mu, m.v - mv)) < 0.02
    assert np.max(np.abs(tv)) > 3.0   # a real stretch, not a trivial shift


def test_translate_truth_and_jump():
    source = SyntheticTranslateSource("synthetic:translate?frames=12&size=128x128&du=0.25&dv=-0.5&jump=10:6:-2&pace=0")
    frames = _frames(source)
    assert source.shift(3) == (0.75, -1.5)
    assert source.shift(10) == (2.5 + 6, -5.0 - 2)
    u, v = frames[10].metadata["truth"](np.array([20.0, 90.0]), np.array([30.0, 64.0]))
    np.testing.assert_allclose(u, 8.5)
    np.testing.assert_allclose(v, -7.0)
    m = measure(frames[0].image, frames[3].image, [(64, 64), (50, 70)], search="exhaustive", subpixel="icgn",
                radius=4)
    np.testing.assert_allclose(m.u, 0.75, atol=0.03)
    np.testing.assert_allclose(m.v, -1.5, atol=0.03)


def test_neck_concentrates_strain_where_designed():
    model = TensileModel((512, 512), 100, strain=0.05, neck=0.15, seed=0)
    Y = np.arange(60.0, 450.0, 0.5)
    last = model.strain_yy(99, Y)
    peak = Y[np.argmax(last)]
    assert abs(peak - model.y_neck) < 1.0
    assert model.y_neck < 256 - 20          # off-centre by design
    assert last.max() > 3 * np.median(last)  # a localised concentration, not uniform strain
    # Before necking the gauge strains uniformly.
    inner = (Y > model.gauge_top + 3 * model.box_edge) & (Y < model.gauge_bottom - 3 * model.box_edge)
    plastic = model.strain_yy(50, Y[inner])
    assert plastic.max() - plastic.min() < 0.01 * plastic.mean()
    # The exact displacement's derivative is that strain (V is its integral).
    x = np.full_like(Y, model.x_centre)
    _, V = model.displacement(99, x, Y)
    np.testing.assert_allclose(np.gradient(V, Y)[5:-5], last[5:-5], atol=2e-4)
    # Lateral contraction: the right edge moves inwards, most at the neck (Poisson 0.5 plastic).
    edge = model.x_centre + model.gauge_half
    u_neck = model.displacement(99, edge, model.y_neck)[0] - model.displacement(99, model.x_centre, model.y_neck)[0]
    u_far = model.displacement(99, edge, 400.0)[0] - model.displacement(99, model.x_centre, 400.0)[0]
    assert u_neck < u_far < 0


def test_measured_strain_peaks_at_the_neck():
    source = SyntheticTensileSource("synthetic:tensile?frames=31&size=256x384&noise=0.5&pace=0")
    frames = _frames(source)
    model = source.model
    ys = np.arange(source.suggested_roi[1] + 12, source.suggested_roi[1] + source.suggested_roi[3] - 12, 6.0)
    points = np.column_stack([np.full(ys.size, model.x_centre), ys])
    tu, tv = source.truth(30, points[:, 0], points[:, 1])
    m = measure(frames[0].image, frames[30].image, points, search="exhaustive", subpixel="icgn", radius=3,
                guess=np.column_stack([np.round(tu), np.round(tv)]), subpixel_options={"max_iterations": 50})
    assert m.ok.mean() > 0.9
    peak = m.y[m.ok][np.argmax(m.vy[m.ok])]
    assert abs(peak - model.y_neck) <= 12


def test_a_consumer_that_prepares_after_the_first_frame_gets_the_rest_paced_not_in_a_burst():
    """The session takes the first frame (its reference), places its points and opens its outputs, then asks
    for more: the frames come at the frame rate from then on, not all at once (a dropping queue dropped them)."""
    source = SyntheticTensileSource("synthetic:tensile?frames=6&size=96x96&fps=40")
    source.prepare()
    frames = iter(source)
    next(frames)
    time.sleep(0.3)                                     # 12 frame periods of preparation
    arrivals = []
    for _ in frames:
        arrivals.append(time.perf_counter())
    assert arrivals[-1] - arrivals[0] >= 4 / 40 - 0.01  # frames 1..5: four periods apart end to end
