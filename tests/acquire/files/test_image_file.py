"""read_grey_image: 8/16-bit grey files, colour notes, clean errors, fuzzing (the images: source is test_image_sequence's)."""

import os

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from livedic.acquire.files.image_file import read_grey_image, read_image_header
from tests.acquire.files.images import COLOUR, GREY8, GREY16, RNG, write

pytestmark = pytest.mark.usefixtures("time_limit")


# --------------------------------------------------------------------------- read_grey_image

@pytest.mark.parametrize("ext", ["png", "tif"])
@pytest.mark.parametrize("image", [GREY8, GREY16], ids=["8bit", "16bit"])
def test_grey_files_read_back_exactly(tmp_path, ext, image):
    result, note = read_grey_image(write(tmp_path / f"a.{ext}", image))
    assert note is None and result.dtype == image.dtype and np.array_equal(result, image)
    assert result.flags.c_contiguous


@pytest.mark.parametrize("ext", ["png", "tif"])
@pytest.mark.parametrize("channels", [3, 4])
def test_colour_is_converted_to_grey_with_a_note(tmp_path, ext, channels):
    image = COLOUR if channels == 3 else np.dstack([COLOUR, np.full(COLOUR.shape[:2], 255, np.uint8)])
    path = write(tmp_path / f"c.{ext}", image)
    result, note = read_grey_image(path)
    assert result.shape == COLOUR.shape[:2] and result.dtype == np.uint8
    assert np.array_equal(result, cv2.cvtColor(COLOUR, cv2.COLOR_BGR2GRAY))
    assert note.startswith(f"{path}: colour image ({channels} channels) converted to grey")


@pytest.mark.parametrize("ext", ["png", "tif"])
def test_grey_stored_as_colour_is_grey_without_a_note(tmp_path, ext):
    """Equal channels (a palette of grey entries decodes to them) are a grey image: exact, no note;
    with an alpha channel only the alpha is mentioned."""
    from PIL import Image
    palette = Image.frombytes("P", GREY8.shape[::-1], GREY8.tobytes())
    palette.putpalette([level for level in range(256) for _ in range(3)])
    path = tmp_path / f"palette.{ext}"
    palette.save(path)
    assert Image.open(path).mode == "P"
    image, note = read_grey_image(path)
    assert note is None and image.dtype == np.uint8 and np.array_equal(image, GREY8)
    image, note = read_grey_image(write(tmp_path / f"rgb.{ext}", np.dstack([GREY8] * 3)))
    assert note is None and np.array_equal(image, GREY8)
    alpha = np.dstack([GREY8] * 3 + [np.full_like(GREY8, 255)])
    image, note = read_grey_image(write(tmp_path / f"rgba.{ext}", alpha))
    assert np.array_equal(image, GREY8) and note.endswith(": grey + alpha image: alpha channel dropped")
    tinted = Image.frombytes("P", GREY8.shape[::-1], GREY8.tobytes())
    tinted.putpalette([c for level in range(256) for c in (level, level, 255 - level)])   # a colour palette
    tinted.save(tmp_path / f"tinted.{ext}")
    _, note = read_grey_image(tmp_path / f"tinted.{ext}")
    assert "colour image (3 channels) converted to grey" in note


def test_16bit_colour_keeps_16_bits(tmp_path):
    colour16 = RNG.integers(0, 65536, (20, 30, 3), dtype=np.uint16)
    result, note = read_grey_image(write(tmp_path / "c16.png", colour16))
    assert result.dtype == np.uint16 and note is not None


@pytest.mark.parametrize("image, problem", [
    (GREY16.astype(np.float32) / 65535, "32-bit float images are not supported: save as 8- or 16-bit grey"),
    (GREY16.astype(np.float64), "64-bit float images are not supported"),
    (GREY16.astype(np.int32), "32-bit integer images are not supported"),
    (GREY16.astype(np.uint32), "32-bit integer images are not supported"),
    ((GREY16 // 2).astype(np.int16), "signed 16-bit images are not supported"),
], ids=["float32", "float64", "int32", "uint32", "int16"])
def test_unsupported_pixel_types_raise_one_line(tmp_path, image, problem):
    path = write(tmp_path / "frame_003.tif", image)
    with pytest.raises(ValueError) as caught:
        read_grey_image(path)
    message = str(caught.value)
    assert message == f"{path}: {problem}" or message.startswith(f"{path}: {problem}")
    assert "\n" not in message


@pytest.mark.parametrize("ext, fraction", [("png", 0.5), ("png", 0.98), ("tif", 0.5), ("tif", 0.98)])
def test_truncated_files_are_detected(tmp_path, ext, fraction):
    path = write(tmp_path / f"t.{ext}", GREY16)
    data = open(path, "rb").read()
    with open(path, "wb") as file:
        file.write(data[:int(len(data) * fraction)])
    with pytest.raises(ValueError, match=f"{path}: truncated"):
        read_grey_image(path)


def test_missing_empty_garbage_and_directory(tmp_path):
    with pytest.raises(ValueError, match="nope.png: file not found"):
        read_grey_image(tmp_path / "nope.png")
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(ValueError, match=r"empty.png: empty file \(0 bytes\)"):
        read_grey_image(tmp_path / "empty.png")
    (tmp_path / "text.tif").write_bytes(b"this is not an image at all\n" * 10)
    with pytest.raises(ValueError, match="text.tif: not an image OpenCV can read"):
        read_grey_image(tmp_path / "text.tif")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    with pytest.raises(ValueError, match="bad.png: truncated or corrupt PNG file"):
        read_grey_image(tmp_path / "bad.png")
    with pytest.raises(ValueError, match="is a directory"):
        read_grey_image(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads everything")
def test_unreadable_file(tmp_path):
    path = write(tmp_path / "locked.png", GREY8)
    os.chmod(path, 0)
    with pytest.raises(ValueError, match="permission denied"):
        read_grey_image(path)


def test_read_errors_from_the_os_are_one_line(tmp_path, monkeypatch):
    """The permission path as root too (root reads everything): simulated through the module's open()."""
    import livedic.acquire.files.image_file as image_io

    def refuse(*_args, **_kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(image_io, "open", refuse, raising=False)
    with pytest.raises(ValueError, match=r"^x.png: cannot read the file: permission denied$"):
        read_grey_image("x.png")

    def broken(*_args, **_kwargs):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(image_io, "open", broken, raising=False)
    with pytest.raises(ValueError, match=r"^x.png: cannot read the file: Input/output error$"):
        read_grey_image("x.png")


VALID = {}


def _valid_files():
    if not VALID:
        for ext in (".png", ".tif"):
            for image in (GREY8, GREY16, COLOUR):
                ok, encoded = cv2.imencode(ext, image)
                VALID.setdefault(ext, []).append(encoded.tobytes())
    return VALID[".png"] + VALID[".tif"]


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(
    st.binary(max_size=4096),
    st.tuples(st.integers(0, 5), st.integers(0, 10**6), st.binary(min_size=1, max_size=16), st.booleans()),
))
def test_fuzz_bytes_only_ever_raise_value_error(tmp_path, case):
    """Random bytes, and valid PNG/TIFF files cut or overwritten at random: a result or ValueError, no crash."""
    if isinstance(case, tuple):
        which, position, patch, cut = case
        data = bytearray(_valid_files()[which])
        position %= len(data)
        if cut:
            data = data[:position]
        else:
            data[position:position + len(patch)] = patch
        data = bytes(data)
    else:
        data = case
    path = tmp_path / "fuzz.img"
    path.write_bytes(data)
    try:
        image, note = read_grey_image(path)
    except ValueError as error:
        assert str(error).startswith(str(path)) and "\n" not in str(error)
    else:
        assert image.ndim == 2 and image.dtype in (np.uint8, np.uint16) and image.size > 0


def test_image_header_agrees_with_the_decoded_image(tmp_path):
    """Size and bit depth from the header alone, as decoding finds them; colour files' bit depth unknown."""
    cases = {"g8.png": GREY8, "g16.png": GREY16, "g8.tif": GREY8, "g16.tif": GREY16, "c8.png": COLOUR,
             "c16.tif": COLOUR.astype(np.uint16) * 257}
    for name, image in cases.items():
        header = read_image_header(write(tmp_path / name, image))
        decoded, _ = read_grey_image(tmp_path / name)
        assert (header.height, header.width) == decoded.shape, name
        expected_bits = decoded.dtype.itemsize * 8 if image.ndim == 2 else None
        assert header.bits == expected_bits, name
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(ValueError, match="empty.png: empty file"):
        read_image_header(tmp_path / "empty.png")


def test_read_same_size_images_reads_all_and_refuses_another_size_in_one_line(tmp_path):
    import cv2
    from livedic.acquire.files.image_file import read_same_size_images
    paths = []
    for name, shape in (("a.png", (6, 5)), ("b.png", (6, 5)), ("c.png", (4, 5))):
        paths.append(str(tmp_path / name))
        cv2.imwrite(paths[-1], np.full(shape, 9, np.uint8))
    images, notes = read_same_size_images(paths[:2])
    assert [image.shape for image in images] == [(6, 5), (6, 5)] and notes == []
    with pytest.raises(ValueError, match=r"c.png is 5x4 but the reference .*a.png is 5x6: static images must"):
        read_same_size_images(paths, "static images")
