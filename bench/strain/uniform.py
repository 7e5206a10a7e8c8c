"""Part a of ``livedic bench strain``: uniform strain on exact 8-bit image pairs, strain error RMS vs VSG.

Two generators that share nothing (speckle, band-limited noise); the target is RMS <= 1e-4 at VSG <= 100 px.
"""

import math

import numpy as np

TARGET_RMS = 1e-4
TARGET_VSG_PX = 100.0
STEP = 5
MARGIN = 48
# Windows per subset at step 5 px: VSG 41 (51 for subset 41), 61, 81, 91, 111 px.
WINDOWS = {21: (5, 9, 13, 15, 19), 31: (3, 7, 11, 13, 17), 41: (3, 5, 9, 11, 15)}
# (name, (ux, uy, vx, vy)) of the affine fields, and their translation (u, v) at the image centre.
STRAIN_CASES = (("0.1 % uniaxial", (-0.0003, 0.0, 0.0, 0.001)), ("1 % uniaxial", (-0.003, 0.0, 0.0, 0.01)),
                ("5 % uniaxial", (-0.015, 0.0, 0.0, 0.05)), ("0.5 % shear", (0.0, 0.01, 0.0, 0.0)))
TRANSLATION = (0.37, -0.21)
GENERATORS = ("speckle R=4", "band-limited noise")
N_WAVES = 2048
WAVE_BLUR = 1.6
NOISE_SIGMA = 1.0


def wave_field(n_waves=N_WAVES, blur=WAVE_BLUR, seed=0):
    """Wave vectors (n, 2) in cycles/px and phases (n,) of a random-phase Gaussian random field.

    The wave vectors are drawn from the power spectrum of white noise low-passed by a Gaussian of
    SD ``blur`` px (``bench.patterns.fft_blurred``): exp(-4 pi^2 blur^2 |k|^2), a Gaussian in k of
    SD 1 / (2 sqrt(2) pi blur) per axis.
    """
    rng = np.random.default_rng(seed)
    sd = 1.0 / (2.0 * math.sqrt(2.0) * math.pi * blur)
    return rng.normal(0.0, sd, size=(n_waves, 2)), rng.uniform(0.0, 2.0 * math.pi, n_waves)


def render_waves(waves, shape, gradient=(0.0, 0.0, 0.0, 0.0), translation=(0.0, 0.0), centre=(0.0, 0.0)):
    """The field sum_k sqrt(2/n) cos(2 pi k.X + phi_k), deformed by an affine map, at the pixel centres.

    Content at X in the reference appears at x = X + t + G (X - c); pixel x shows the reference at
    X = c + A^-1 (x - c - t), A = I + G, so each wave keeps its form with wave vector A^-T k.
    """
    k, phase = waves
    height, width = shape
    a = np.eye(2) + np.asarray(gradient, dtype=np.float64).reshape(2, 2)
    deformed_k = k @ np.linalg.inv(a)
    c, t = np.asarray(centre, dtype=np.float64), np.asarray(translation, dtype=np.float64)
    phase0 = 2.0 * math.pi * (k @ c - deformed_k @ (c + t)) + phase
    along_x = 2.0 * math.pi * deformed_k[:, :1] * np.arange(width)[None, :] + phase0[:, None]
    along_y = 2.0 * math.pi * deformed_k[:, 1:] * np.arange(height)[None, :]
    image = np.cos(along_y).T @ np.cos(along_x) - np.sin(along_y).T @ np.sin(along_x)
    return image * math.sqrt(2.0 / len(phase))


def uniform_pair(generator, size, gradient, *, seed):
    """An 8-bit (reference, deformed) pair of ``generator`` under the affine field (noise sigma 1, independent)."""
    from livedic.bench.patterns import to_8bit
    centre = ((size - 1) / 2.0, (size - 1) / 2.0)
    if generator == "speckle R=4":
        from livedic.dic.speckle import SpecklePattern, affine, render
        pattern = SpecklePattern((size, size), density=1000 / 256 ** 2, radius=4.0, seed=seed)
        reference = render(pattern, bit_depth=None)
        deformed = render(pattern, affine(*TRANSLATION, *gradient, centre=centre), bit_depth=None)
        scale = 200.0 / np.percentile(reference, 99.5)
        reference, deformed = 20.0 + scale * reference, 20.0 + scale * deformed
    elif generator == "band-limited noise":
        waves = wave_field(seed=seed)
        reference = render_waves(waves, (size, size))
        deformed = render_waves(waves, (size, size), gradient, TRANSLATION, centre)
        lo, hi = np.percentile(reference, [0.5, 99.5])
        reference, deformed = (20.0 + (image - lo) * 215.0 / (hi - lo) for image in (reference, deformed))
    else:
        raise ValueError(f"unknown generator {generator!r}: one of {', '.join(GENERATORS)}")
    return to_8bit(reference, NOISE_SIGMA, 2 * seed + 1), to_8bit(deformed, NOISE_SIGMA, 2 * seed + 2)


def rms(values):
    """Root mean square of ``values``; NaN for none."""
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else float("nan")


def uniform_strain_study(*, quick, say):
    """Part a: rows (dicts) of strain error RMS per generator, strain case, subset and window."""
    from livedic.dic import measure
    from livedic.dic.strain import strain_field, strain_window

    size = 384 if quick else 512
    subsets = (21,) if quick else (21, 31, 41)
    axis = np.arange(MARGIN, size - MARGIN, STEP, dtype=np.float64)
    points = np.column_stack([a.ravel() for a in np.meshgrid(axis, axis)])
    say(f"a. uniform strain: {size}x{size} 8-bit pairs, noise sigma {NOISE_SIGMA:g} grey level on each image, "
        f"translation ({TRANSLATION[0]:g}, {TRANSLATION[1]:g}) px; dic.measure (improved-wso + icgn, guided) on "
        f"{len(points):,} points every {STEP} px; engineering strain; |grad|^2: the reference's mean squared "
        f"intensity gradient (grey levels^2/px^2: the texture that sets the displacement noise); cells: RMS error "
        f"exx/eyy/exy in microstrain")
    vsg_columns = (41, 61, 81, 91, 111)
    header = (f"  {'generator':20s} {'case':15s} {'|grad|^2':>8s} {'subset':>6s} {'disp RMS':>8s} "
              + " ".join(f"{f'VSG {v}' if v != 41 else 'VSG 41/51':>15s}" for v in vsg_columns))
    say(header)
    rows = []
    for g, generator in enumerate(GENERATORS):
        for case, gradient in STRAIN_CASES:
            reference, deformed = uniform_pair(generator, size, gradient, seed=7 + g)
            ux, uy, vx, vy = gradient
            exact = (ux, vy, 0.5 * (uy + vx))
            centre = (size - 1) / 2.0
            gy, gx = np.gradient(reference.astype(np.float64))
            texture = float(np.mean((gx * gx + gy * gy)[MARGIN:-MARGIN, MARGIN:-MARGIN]))
            for subset in subsets:
                m = measure(reference, deformed, points, subset=subset, subpixel="icgn")
                du = m.u - (TRANSLATION[0] + ux * (m.x - centre) + uy * (m.y - centre))
                dv = m.v - (TRANSLATION[1] + vx * (m.x - centre) + vy * (m.y - centre))
                disp_rms = rms(np.hypot(du, dv)[m.ok])
                cells = []
                for window in WINDOWS[subset]:
                    field = strain_field(strain_window(points, window=window, step=STEP, subset=subset),
                                         m.u, m.v, m.ok)
                    ok = field.ok
                    errors = [c[ok] - e for c, e in zip((field.exx, field.eyy, field.exy), exact)]
                    row = dict(generator=generator, case=case, ux=ux, uy=uy, vx=vx, vy=vy, subset=subset, step=STEP,
                               window=window, vsg_px=field.vsg_px, points=len(points),
                               displacement_ok=float(m.ok.mean()), strain_ok=float(ok.mean()),
                               displacement_rms_px=disp_rms, mean_gradient2=texture,
                               rms_exx=rms(errors[0]), rms_eyy=rms(errors[1]), rms_exy=rms(errors[2]),
                               bias_exx=float(np.mean(errors[0])), bias_eyy=float(np.mean(errors[1])),
                               bias_exy=float(np.mean(errors[2])))
                    row["rms_max"] = max(row["rms_exx"], row["rms_eyy"], row["rms_exy"])
                    rows.append(row)
                    cells.append(f"{1e6 * row['rms_exx']:4.0f}/{1e6 * row['rms_eyy']:4.0f}/{1e6 * row['rms_exy']:4.0f}")
                say(f"  {generator:20s} {case:15s} {texture:8.0f} {subset:6d} {disp_rms:8.4f} "
                    + " ".join(f"{c:>15s}" for c in cells))
    return rows


def judge_uniform(rows):
    """(met: bool, lines) for the target RMS <= 1e-4 at VSG <= 100 px, per generator and strain case."""
    lines = []
    met_all = True
    default_all = True
    for generator in GENERATORS:
        for case, _ in STRAIN_CASES:
            mine = [r for r in rows if r["generator"] == generator and r["case"] == case
                    and r["vsg_px"] <= TARGET_VSG_PX]
            if not mine:
                continue
            best = min(mine, key=lambda r: r["rms_max"])
            default = max((r for r in mine if r["subset"] == 21), key=lambda r: r["vsg_px"], default=None)
            met = best["rms_max"] <= TARGET_RMS
            default_met = default is not None and default["rms_max"] <= TARGET_RMS
            met_all &= met
            default_all &= default_met
            text = (f"  {generator:20s} {case:15s} best at VSG <= {TARGET_VSG_PX:g} px: "
                    f"{1e6 * best['rms_max']:.0f} microstrain (subset {best['subset']}, window {best['window']}, "
                    f"VSG {best['vsg_px']:g} px) {'met' if met else 'NOT met'}")
            if default is not None:
                text += (f"; subset 21, VSG {default['vsg_px']:g} px: {1e6 * default['rms_max']:.0f} "
                         f"{'met' if default_met else 'NOT met'}")
            lines.append(text)
    verdict = (f"{'MET' if met_all else 'NOT MET'}  target strain error RMS <= 1e-4 (100 microstrain) at VSG <= "
               f"{TARGET_VSG_PX:g} px, 8-bit, noise sigma 1 (worst component of exx, eyy, exy, every generator and "
               f"case, best subset/window): {'met' if met_all else 'not met'}; with the default subset 21 alone: "
               f"{'met' if default_all else 'not met'}")
    return met_all, default_all, lines, verdict
