"""Speckle images from generators other than livedic's simulator, for validation.

``dic.speckle`` renders Zhou-Goodson Gaussian speckle exactly; a measurement
validated only on its own simulator can hide a bias towards it. These
generators share nothing with it:

* ``fft_blurred``: white noise low-passed by a Gaussian in the Fourier domain
  (a "sand-blasted" texture with no distinct spots); the deformed image is the
  same spectrum times the shift's phase ramp, so the shift is exact for any
  sub-pixel value (periodic: content leaving one side enters on the other).
* ``sparse_dots``: few isotropic Gaussian dots on a flat background (about
  ``dots_per_subset`` dots in a 21 x 21 subset), the case where one or two dots
  cannot pin a first-order warp; rendered analytically at shifted centres.
* ``hard_discs``: non-overlapping-agnostic hard discs of radius ``radius`` (2-5 px,
  paint-like edges), area-integrated by 4 x 4 supersampling; shift analytic.

All return float64 images in grey levels (0..255 scale) before noise and
quantisation; ``to_8bit`` adds Gaussian noise and rounds. ``pair`` makes an
8-bit pair by name, livedic's own simulator included, for the benchmarks.
"""

import numpy as np


def fft_blurred(shape, shift=(0.0, 0.0), *, blur=1.6, seed=0):
    """Reference and shifted image pair of Gaussian-filtered white noise.

    Parameters
    ----------
    shape : (H, W)
        Image size.
    shift : (u, v)
        Displacement of the content, px (content at x in the reference is at x + u).
    blur : float
        Gaussian filter SD in px (speckle correlation length ~ 2 blur).
    seed : int
        Noise seed.

    Returns
    -------
    reference, deformed : ndarray of float64, shape (H, W)
        Scaled to about 20..235 grey levels.
    """
    height, width = shape
    rng = np.random.default_rng(seed)
    spectrum = np.fft.fft2(rng.standard_normal((height, width)))
    ky = np.fft.fftfreq(height)[:, None]
    kx = np.fft.fftfreq(width)[None, :]
    spectrum *= np.exp(-2.0 * (np.pi * blur) ** 2 * (kx * kx + ky * ky))
    reference = np.fft.ifft2(spectrum).real
    ramp = np.exp(-2j * np.pi * (kx * shift[0] + ky * shift[1]))
    deformed = np.fft.ifft2(spectrum * ramp).real
    lo, hi = np.percentile(reference, [0.5, 99.5])
    scale = 215.0 / (hi - lo)
    return 20.0 + (reference - lo) * scale, 20.0 + (deformed - lo) * scale


def _splat(shape, xs, ys, amplitude, sigma, background):
    height, width = shape
    image = np.full(shape, float(background))
    reach = int(np.ceil(4 * sigma))
    for x, y, a in zip(xs, ys, amplitude):
        c0, c1 = max(int(np.floor(x)) - reach, 0), min(int(np.floor(x)) + reach + 2, width)
        r0, r1 = max(int(np.floor(y)) - reach, 0), min(int(np.floor(y)) + reach + 2, height)
        if c0 >= c1 or r0 >= r1:
            continue
        gx = np.exp(-0.5 * ((np.arange(c0, c1) - x) / sigma) ** 2)
        gy = np.exp(-0.5 * ((np.arange(r0, r1) - y) / sigma) ** 2)
        image[r0:r1, c0:c1] += a * gy[:, None] * gx[None, :]
    return image


def sparse_dots(shape, shift=(0.0, 0.0), *, dots_per_subset=4.0, sigma=1.5, seed=0):
    """Reference and shifted image of sparse Gaussian dots (about ``dots_per_subset`` per 21 x 21 px).

    Returns
    -------
    reference, deformed : ndarray of float64, shape (H, W)
        Background 30 grey levels, dots 150-210 high.
    """
    height, width = shape
    rng = np.random.default_rng(seed)
    margin = 64.0
    area = (height + 2 * margin) * (width + 2 * margin)
    count = int(round(dots_per_subset / 441.0 * area))
    xs = rng.uniform(-margin, width + margin, count)
    ys = rng.uniform(-margin, height + margin, count)
    amplitude = rng.uniform(150.0, 210.0, count)
    reference = _splat(shape, xs, ys, amplitude, sigma, 30.0)
    deformed = _splat(shape, xs + shift[0], ys + shift[1], amplitude, sigma, 30.0)
    return np.minimum(reference, 250.0), np.minimum(deformed, 250.0)


def hard_discs(shape, shift=(0.0, 0.0), *, radius=3.0, coverage=0.5, seed=0, supersample=4):
    """Reference and shifted image of black discs of ``radius`` px on white, area-integrated.

    ``coverage`` is the expected painted fraction (discs overlap freely).

    Returns
    -------
    reference, deformed : ndarray of float64, shape (H, W)
        White 220, black 35 grey levels.
    """
    height, width = shape
    rng = np.random.default_rng(seed)
    margin = 2 * radius + 64
    area = (height + 2 * margin) * (width + 2 * margin)
    count = int(round(-np.log(1.0 - coverage) * area / (np.pi * radius * radius)))
    xs = rng.uniform(-margin, width + margin, count)
    ys = rng.uniform(-margin, height + margin, count)

    def paint(dx, dy):
        s = supersample
        offsets = (np.arange(s) + 0.5) / s - 0.5
        ink = np.zeros((height * s, width * s), dtype=bool)
        fine_x = (np.arange(width)[:, None] + offsets[None, :]).ravel()
        fine_y = (np.arange(height)[:, None] + offsets[None, :]).ravel()
        reach = radius + 1
        for x, y in zip(xs + dx, ys + dy):
            c0 = np.searchsorted(fine_x, x - reach)
            c1 = np.searchsorted(fine_x, x + reach)
            r0 = np.searchsorted(fine_y, y - reach)
            r1 = np.searchsorted(fine_y, y + reach)
            if c0 >= c1 or r0 >= r1:
                continue
            inside = ((fine_x[None, c0:c1] - x) ** 2 + (fine_y[r0:r1, None] - y) ** 2) <= radius * radius
            ink[r0:r1, c0:c1] |= inside
        fraction = ink.reshape(height, s, width, s).mean(axis=(1, 3))
        return 220.0 - 185.0 * fraction

    return paint(0.0, 0.0), paint(shift[0], shift[1])


def to_8bit(image, noise_sigma=0.0, seed=0):
    """``image`` plus Gaussian noise of ``noise_sigma`` grey levels, rounded and clipped to uint8."""
    rng = np.random.default_rng(seed)
    noisy = image + (rng.normal(0.0, noise_sigma, image.shape) if noise_sigma > 0 else 0.0)
    return np.clip(np.floor(noisy + 0.5), 0, 255).astype(np.uint8)




GENERATORS = ("simulator R=4", "simulator R=2", "simulator R=5", "fft-filtered noise", "sparse dots",
              "hard discs R=3")


def pair(generator, shape, shift, *, noise_sigma, seed, contrast=None):
    """An 8-bit (reference, deformed) pair of ``generator`` (one of ``GENERATORS``) shifted by ``shift``.

    ``simulator R=r`` is livedic's Zhou-Goodson simulator (``dic.speckle``) at the paper's
    coverage for any speckle radius r (1000 speckles of R = 4 per 256^2), its exact
    intensities scaled to 20..220 grey levels. ``contrast`` squeezes the pair into that
    many grey levels around 110 (a dim specimen). Independent Gaussian noise of
    ``noise_sigma`` grey levels on each image, then rounding.
    """
    if generator.startswith("simulator R="):
        from livedic.dic.speckle import SpecklePattern, render
        r = float(generator.split("=")[1])
        pattern = SpecklePattern(shape, density=1000 / 256 ** 2 * (4.0 / r) ** 2, radius=r, seed=seed)
        a, b = render(pattern, bit_depth=None), render(pattern, shift, bit_depth=None)
        scale = 200.0 / np.percentile(a, 99.5)
        a, b = 20.0 + scale * a, 20.0 + scale * b
    elif generator == "fft-filtered noise":
        a, b = fft_blurred(shape, shift, seed=seed)
    elif generator == "sparse dots":
        a, b = sparse_dots(shape, shift, seed=seed)
    elif generator.startswith("hard discs R="):
        a, b = hard_discs(shape, shift, radius=float(generator.split("=")[1]), seed=seed)
    else:
        raise ValueError(f"unknown pattern generator {generator!r}: one of {', '.join(GENERATORS)}")
    if contrast is not None:
        lo, hi = np.percentile(a, [0.5, 99.5])
        a, b = (110.0 + (image - 0.5 * (lo + hi)) * contrast / (hi - lo) for image in (a, b))
    return to_8bit(a, noise_sigma, 2 * seed + 1), to_8bit(b, noise_sigma, 2 * seed + 2)
