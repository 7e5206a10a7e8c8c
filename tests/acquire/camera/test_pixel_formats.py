"""Pixel formats: unpacking Mono10p, Mono12p, Mono10Packed and Mono12Packed bit for bit.

The packed buffers below are written out by hand from the layouts (PFNC for the "p"
formats: one little-endian bit stream; GigE Vision for "Packed": high bits in bytes 0
and 2, the low bits of both pixels in byte 1), not produced by ``pack``.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from livedic.acquire.camera.pixel_formats import FORMATS, FRAME_BIT_DEPTH, by_code, by_name, pack, unpack

HAND_PACKED = [
    # Mono12p: p0 = 0xABC -> byte0 = 0xBC, byte1 = p0[11:8] 0xA | p1[3:0] 0x3 << 4, byte2 = p1[11:4] 0x12
    ("Mono12p", [0xABC, 0x123], [0xBC, 0x3A, 0x12]),
    # Mono12Packed: byte0 = p0[11:4] 0xAB, byte1 = p0[3:0] 0xC | p1[3:0] 0x3 << 4, byte2 = p1[11:4] 0x12
    ("Mono12Packed", [0xABC, 0x123], [0xAB, 0x3C, 0x12]),
    # Mono10p, 40 bits LSB first: p0 = 0x3FF in bits 0-9, p1 = 0x001 in 10-19, p2 = 0x2AA in 20-29,
    # p3 = 0x155 in 30-39 -> 0xFF, 0b000001_11, 0b1010_0000, 0b01_101010, 0b01010101
    ("Mono10p", [0x3FF, 0x001, 0x2AA, 0x155], [0xFF, 0x07, 0xA0, 0x6A, 0x55]),
    # Mono10Packed: byte0 = p0[9:2] 0xFF, byte1 = p0[1:0] 0b11 | p1[1:0] 0b01 << 4, byte2 = p1[9:2] 0x55
    ("Mono10Packed", [0x3FF, 0x155], [0xFF, 0x13, 0x55]),
]


@pytest.mark.parametrize("name, pixels, raw", HAND_PACKED)
def test_hand_packed_buffers_unpack_bit_exactly(name, pixels, raw):
    fmt = FORMATS[name]
    image = unpack(np.array(raw, np.uint8), fmt, len(pixels), 1)
    assert image.dtype == np.uint16 and image.tolist() == [pixels]
    assert pack(np.array([pixels]), fmt).tolist() == raw


def test_a_packed_stream_runs_across_lines_unless_lines_are_padded():
    # Mono12p, 3 x 2 pixels: the 6 pixels are one bit stream, line 0 ends inside byte 4
    values = [[0x001, 0x002, 0x003], [0xFFF, 0x800, 0x7FF]]
    raw = [0x01, 0x20, 0x00, 0x03, 0xF0, 0xFF, 0x00, 0xF8, 0x7F]
    assert unpack(np.array(raw, np.uint8), FORMATS["Mono12p"], 3, 2).tolist() == values
    # the same lines padded to 6 bytes each (the camera's x padding): each line starts on a byte
    line0 = [0x01, 0x20, 0x00, 0x03, 0x00]          # 3 pixels = 36 bits -> 5 bytes, the last half used
    line1 = [0xFF, 0x0F, 0x80, 0xFF, 0x07]
    padded = np.array(line0 + [0xEE] + line1 + [0xEE], np.uint8)
    assert unpack(padded, FORMATS["Mono12p"], 3, 2, row_stride=6).tolist() == values


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["Mono10p", "Mono12p", "Mono10Packed", "Mono12Packed"]),
       width=st.integers(1, 37), height=st.integers(1, 9), seed=st.integers(0, 2**32 - 1))
def test_pack_then_unpack_gives_the_image_back(name, width, height, seed):
    fmt = FORMATS[name]
    image = np.random.default_rng(seed).integers(0, 1 << fmt.bit_depth, (height, width)).astype(np.uint16)
    raw = pack(image, fmt)
    assert raw.size == -(-width * height * fmt.bits_per_pixel // 8)    # what the camera sends
    assert np.array_equal(unpack(raw, fmt, width, height), image)


def test_formats_know_their_codes_depths_and_wire_sizes():
    assert by_code(0x010C0047).name == "Mono12p" and by_code(0x010C0006).name == "Mono12Packed"
    assert by_code(0x01080009) is None                                  # BayerRG8: not read
    assert by_name("mono10P") is FORMATS["Mono10p"] and by_name("Mono14") is None
    assert [FORMATS[n].bits_per_pixel for n in ("Mono8", "Mono12", "Mono10p", "Mono10Packed")] == [8, 16, 10, 12]
    assert FORMATS["Mono12Packed"].frame_format == "Mono12" and FORMATS["Mono8"].dtype == np.uint8
    assert FRAME_BIT_DEPTH == {"Mono8": 8, "Mono10": 10, "Mono12": 12, "Mono16": 16}


def test_short_buffers_and_values_too_wide_are_refused():
    with pytest.raises(ValueError, match="needs 6 bytes, got 5"):
        unpack(np.zeros(5, np.uint8), FORMATS["Mono12p"], 2, 2)
    with pytest.raises(ValueError, match="12-bit values"):
        pack(np.array([[4096]]), FORMATS["Mono12p"])
    with pytest.raises(ValueError, match="not a packed format"):
        unpack(np.zeros(8, np.uint8), FORMATS["Mono16"], 2, 2)


def test_a_12_bit_camera_is_tracked_as_its_8_bit_twin():
    """No grey-level threshold assumes 8 bits or a full 16-bit range: the same scene with 4 more bits
    (x 16, what a 12-bit camera holds in its uint16) gives the same points, statuses and displacements,
    a hole and a flat background included (the texture gate and P0's choice are relative)."""
    from livedic import dic
    from livedic.dic.speckle import SpecklePattern, affine, render
    from livedic.stream.session.p0 import choose_p0

    pattern = SpecklePattern((160, 200), radius=3.0, seed=11)
    reference = render(pattern, bit_depth=8)
    deformed = render(pattern, affine(u=0.6, v=-0.3, vy=0.004, centre=(100, 80)), bit_depth=8)
    for image in (reference, deformed):
        image[:, :40] = 30                                   # background
        image[60:100, 120:160] = 250                         # a saturated hole
    points = [(x, y) for y in range(20, 141, 12) for x in range(20, 181, 12)]
    eight = dic.measure(reference, deformed, points, subpixel="icgn")
    twelve = dic.measure(reference.astype(np.uint16) << 4, deformed.astype(np.uint16) << 4, points,
                         subpixel="icgn")
    assert 0 < eight.ok.sum() < len(points)                   # the gates had something to say
    assert np.array_equal(twelve.status, eight.status)
    np.testing.assert_allclose(twelve.u[eight.ok], eight.u[eight.ok], atol=1e-6)
    np.testing.assert_allclose(twelve.v[eight.ok], eight.v[eight.ok], atol=1e-6)
    np.testing.assert_allclose(twelve.zncc[eight.ok], eight.zncc[eight.ok], atol=1e-9)
    assert choose_p0(reference.astype(np.uint16) << 4, None, 21) == choose_p0(reference, None, 21)
