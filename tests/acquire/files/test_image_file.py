"""read_grey_image and the images: source: 8/16-bit grey files, colour notes, clean errors, fuzzing."""

import os
import time

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from livedic.acquire.base import SourceError
from livedic.acquire.files.image_file import read_grey_image, read_image_header
from livedic.acquire.files.image_sequence import ImageSequence, natural_key, open_uri

pytestmark = pytest.mark.usefixtures("time_limit")

RNG = np.random.default_rng(7)
GREY8 = RNG.integers(0, 256, (37, 53), dtype=np.uint8)
GREY16 = RNG.integers(0, 65536, (37, 53), dtype=np.uint16)
COLOUR = RNG.integers(0, 256, (37, 53, 3), dtype=np.uint8)


def write(path, image):
    assert cv2.imwrite(str(path), image), path
    return str(path)


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


# --------------------------------------------------------------------------- images: source

def test_natural_order():
    names = ["frame_10.png", "frame_2.png", "frame_1.png", "Frame_3.png", "frame_100.png", "frame_2b.png"]
    assert sorted(names, key=natural_key) == ["frame_1.png", "frame_2.png", "frame_2b.png", "Frame_3.png",
                                              "frame_10.png", "frame_100.png"]


def test_sequence_yields_files_in_natural_order(tmp_path):
    for i in (10, 2, 1, 33):
        write(tmp_path / f"frame_{i}.tif", np.full((8, 9), i, np.uint16))
    with open_uri(f"images:{tmp_path}/frame_*.tif", frame_rate=10) as source:
        frames = list(source)
        settings = source.settings
    assert [int(f.image[0, 0]) for f in frames] == [1, 2, 10, 33]
    assert [f.index for f in frames] == [0, 1, 2, 3]
    assert [f.timestamp_ns for f in frames] == [0, 100_000_000, 200_000_000, 300_000_000]
    assert all(f.pixel_format == "Mono16" and f.image.dtype == np.uint16 for f in frames)
    assert frames[2].metadata["path"].endswith("frame_10.tif")
    assert settings["n_files"] == 4 and settings["pixel_format"] == "Mono16" and settings["width"] == 9
    # a folder works too, and picks PNG/TIFF only
    (tmp_path / "notes.txt").write_text("x")
    assert len(list(ImageSequence(tmp_path))) == 4


def test_sequence_colour_note_once(tmp_path, caplog):
    for i in range(3):
        write(tmp_path / f"c{i}.png", COLOUR)
    with caplog.at_level("WARNING", logger="livedic.acquire.images"):
        frames = list(ImageSequence(tmp_path / "c*.png"))
    assert len(frames) == 3 and frames[0].image.ndim == 2
    assert len([r for r in caplog.records if "converted to grey" in r.message]) == 1
    assert "note" in frames[0].metadata


def test_sequence_errors(tmp_path):
    with pytest.raises(SourceError, match="no image files match"):
        open_uri(f"images:{tmp_path}/none_*.png")
    with pytest.raises(SourceError, match="unknown images option"):
        open_uri(f"images:{tmp_path}", fps=3)
    write(tmp_path / "f1.png", GREY8)
    write(tmp_path / "f2.png", GREY16)
    (tmp_path / "f3.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    with pytest.raises(SourceError, match="f2.png is 16-bit but the first image .*f1.png is 8-bit"):
        ImageSequence(tmp_path / "f*.png")         # from the headers, before any frame
    os.remove(tmp_path / "f2.png")
    with pytest.raises(SourceError, match="f3.png: truncated or corrupt PNG"):
        ImageSequence(tmp_path / "f*.png")         # no header Pillow knows: decoded, and refused, up front
    (tmp_path / "f3.png").write_bytes(open(write(tmp_path / "f4.png", GREY8), "rb").read()[:200])
    source = ImageSequence(tmp_path / "f*.png")    # the header is whole: found when its turn comes
    iterator = iter(source)
    assert next(iterator).image.dtype == np.uint8
    with pytest.raises(SourceError, match="f3.png: truncated"):
        next(iterator)
    # colour files do not show their bit depth in their header: refused when their turn comes
    write(tmp_path / "h1.png", COLOUR)
    write(tmp_path / "h2.png", COLOUR.astype(np.uint16) * 257)
    iterator = iter(ImageSequence(tmp_path / "h*.png"))
    next(iterator)
    with pytest.raises(SourceError, match="h2.png: 53x37 uint16 differs from the first image"):
        next(iterator)
    write(tmp_path / "g1.tif", GREY16.astype(np.float32))
    with pytest.raises(SourceError, match="g1.tif: 32-bit float images are not supported"):
        list(ImageSequence(tmp_path / "g*.tif"))


@pytest.mark.parametrize("ext", ["png", "tif"])
def test_sequence_of_another_size_is_refused_before_the_first_frame(tmp_path, ext):
    """One file of another size among many: refused when the source opens, naming it and both sizes."""
    for i in range(6):
        write(tmp_path / f"s{i}.{ext}", GREY16[:-3] if i == 4 else GREY16)
    with pytest.raises(SourceError) as refused:
        ImageSequence(tmp_path)
    message = str(refused.value)
    assert message == (f"{tmp_path}/s4.{ext} is 53x34 but the first image {tmp_path}/s0.{ext} is 53x37: every image "
                       f"of a sequence must have the same size (remove it, or crop all images alike)")


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


def test_sequence_options_in_the_uri_and_question_mark_still_a_wildcard(tmp_path):
    """``images:GLOB?frame_rate=5`` as docs/guide/sources.md gives it (the command line has no other way to pass it);
    a ``?`` not followed by name=value pairs is the glob's own wildcard."""
    for i in (1, 2, 3):
        write(tmp_path / f"q{i}.png", GREY8)
    with open_uri(f"images:{tmp_path}/q*.png?frame_rate=5&loop=0") as source:
        assert len(source) == 3 and source.frame_rate == 5.0 and not source.loop
        assert [f.timestamp_ns for f in source] == [0, 200_000_000, 400_000_000]
    with open_uri(f"images:{tmp_path}/q?.png") as source:
        assert len(source) == 3 and source.frame_rate == 1.0
    assert open_uri(f"images:{tmp_path}/q*.png?frame_rate=5", frame_rate=2).frame_rate == 2.0   # keywords win
    with pytest.raises(SourceError, match="unknown images option.s. fps; known: frame_rate"):
        open_uri(f"images:{tmp_path}/q*.png?fps=5")


def test_sequence_realtime_and_loop(tmp_path):
    for i in range(3):
        write(tmp_path / f"r{i}.png", GREY8)
    start = time.monotonic()
    frames = []
    with ImageSequence(tmp_path, frame_rate=50, realtime=True, loop=True) as source:
        for frame in source:
            frames.append(frame)
            if len(frames) == 7:
                break
    assert [f.index for f in frames] == list(range(7))
    assert time.monotonic() - start >= 6 / 50 * 0.9
