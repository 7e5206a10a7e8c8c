"""A reference and a frame of different bit depths (16-bit against 8-bit): measured as well as at one depth, and
warned about once (``stream.pipeline.sinks.bit_depth_change``), in ``livedic measure`` and in a session."""

import cv2
import numpy as np
import pytest

from livedic.acquire.base import Frame, FrameSource
from livedic.stream.cli import main
from livedic.stream.session.config import SessionConfig, ViewerConfig
from livedic.stream.session.session import Session

SHIFT = (1.3, -0.7)           # px, x then y: the deformed image's content moved by this


def _speckle(shift=(0.0, 0.0), size=(160, 192)):
    """Grey levels in [0.1, 0.9] of full scale: Gaussian-filtered noise, its content moved by ``shift`` exactly
    (a phase ramp in the Fourier domain: the pattern is band-limited and periodic, so nothing is interpolated)."""
    noise = np.random.default_rng(11).standard_normal(size)
    fy, fx = np.fft.fftfreq(size[0])[:, None], np.fft.fftfreq(size[1])[None, :]
    spectrum = np.fft.fft2(noise) * np.exp(-2 * (np.pi * 2.0) ** 2 * (fx ** 2 + fy ** 2))   # sigma 2 px blur
    pattern = np.fft.ifft2(spectrum).real
    moved = np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (fx * shift[0] + fy * shift[1]))).real
    return 0.1 + 0.8 * (moved - pattern.min()) / (pattern.max() - pattern.min())


def _quantised(image, bits):
    full = (1 << bits) - 1
    return np.round(image * full).astype(np.uint8 if bits == 8 else np.uint16)


def _measure(tmp_path, capsys, ref_bits, def_bits):
    ref, deformed = tmp_path / f"ref{ref_bits}.png", tmp_path / f"def{def_bits}.png"
    cv2.imwrite(str(ref), _quantised(_speckle(), ref_bits))
    cv2.imwrite(str(deformed), _quantised(_speckle(SHIFT), def_bits))
    out = tmp_path / f"{ref_bits}_{def_bits}.csv"
    assert main(["measure", str(ref), str(deformed), "--grid", "24", "-o", str(out), "--progress", "off"]) == 0
    table = np.genfromtxt(out, delimiter=",", names=True)
    return table, capsys.readouterr().err.splitlines(), (ref, deformed)


def test_measure_of_a_16_bit_reference_against_an_8_bit_image_is_right_and_warned(tmp_path, capsys):
    same, same_err, _ = _measure(tmp_path, capsys, 8, 8)
    mixed, mixed_err, (ref, deformed) = _measure(tmp_path, capsys, 16, 8)
    assert not any("warning" in line for line in same_err)
    warnings = [line for line in mixed_err if line.startswith("livedic: warning: ")]
    assert warnings == [f"livedic: warning: {deformed} is 8-bit but the reference {ref} is 16-bit: measured anyway "
                        f"(ZNCC does not depend on the grey-level scale), but the grey levels of the two differ in "
                        f"resolution; check both were taken with the same camera settings"]
    # Why a warning and not a refusal: the same points are ok, and they moved as at one bit depth.
    ok = same["ok"] == 1                                 # (the points at the border are not)
    assert np.array_equal(mixed["ok"], same["ok"]) and ok.sum() >= 30
    assert np.abs(mixed["u"][ok] - SHIFT[0]).max() < 0.02 and np.abs(mixed["v"][ok] - SHIFT[1]).max() < 0.02
    assert np.abs(mixed["u"] - same["u"])[ok].max() < 0.01 and np.abs(mixed["v"] - same["v"])[ok].max() < 0.01


class _Frames(FrameSource):
    """A 16-bit reference, then frames of the same speckle moved by ``SHIFT``, at ``bits``."""

    def __init__(self, bits):
        self.bits = bits

    def __iter__(self):
        yield Frame(0, 0, _quantised(_speckle(), 16), "Mono16")
        for index in range(1, 4):
            yield Frame(index, index * 10_000_000, _quantised(_speckle(SHIFT), self.bits), f"Mono{self.bits}")

    def close(self):
        pass


def _session(bits):
    said, tracked = [], []
    config = SessionConfig(source="images:frames", viewer=ViewerConfig("none"), record=None, warm_up=False,
                           show_progress=False, drop="block")
    with Session(config, source=_Frames(bits), sinks=[lambda result, stats: tracked.append(result.measurement)],
                 say=said.append) as session:
        session.execute()
    return said, tracked


@pytest.mark.time_limit(300)
@pytest.mark.usefixtures("time_limit")
def test_a_session_whose_frames_change_bit_depth_warns_once_and_tracks_on():
    said, tracked = _session(8)
    warnings = [line for line in said if "bit" in line]
    assert warnings == ["warning: frame 1 is 8-bit but the reference frame 0 is 16-bit: measured anyway (ZNCC does "
                        "not depend on the grey-level scale), but the grey levels of the two differ in resolution; "
                        "check both were taken with the same camera settings"]
    said_alike, alike = _session(16)
    assert not any("bit" in line for line in said_alike)
    assert len(tracked) == len(alike) == 4
    for mixed, same in zip(tracked[1:], alike[1:]):
        ok = same.ok                                     # (not at the border: those subsets move off the image)
        assert np.array_equal(mixed.ok, ok) and ok.mean() > 0.8
        assert np.abs(mixed.u[ok] - SHIFT[0]).max() < 0.02 and np.abs(mixed.v[ok] - SHIFT[1]).max() < 0.02
        assert np.abs(mixed.u - same.u)[ok].max() < 0.01 and np.abs(mixed.v - same.v)[ok].max() < 0.01
