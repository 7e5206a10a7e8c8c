"""Tests of acquire/files/image_sequence.py: the images: source, files in natural order, refused up front or named."""

import os
import time

import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.files.image_sequence import ImageSequence, natural_key, open_uri
from tests.acquire.files.images import COLOUR, GREY8, GREY16, write

pytestmark = pytest.mark.usefixtures("time_limit")


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


def test_natural_order_of_paths_compares_every_digit_run():
    names = ["run10/f_2.png", "run9/f_10.png", "run9/f_9.png", "RUN10/f_1.png"]
    assert sorted(names, key=natural_key) == ["run9/f_9.png", "run9/f_10.png", "RUN10/f_1.png", "run10/f_2.png"]


def test_recursive_glob_and_uri_errors(tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    write(tmp_path / "a" / "f1.png", GREY8)
    write(tmp_path / "a" / "b" / "f2.png", GREY8)
    found = ImageSequence(f"{tmp_path}/**/*.png").files                # sorted by the whole path
    assert [os.path.relpath(p, tmp_path) for p in found] == ["a/b/f2.png", "a/f1.png"]
    with pytest.raises(SourceError, match="needs a glob or folder"):
        open_uri("images:")
    with pytest.raises(SourceError, match="not an images URI"):
        open_uri(f"video:{tmp_path}/a")
    with pytest.raises(SourceError, match="frame_rate=0"):
        ImageSequence(tmp_path / "a", frame_rate=0)


def test_close_ends_the_iteration(tmp_path):
    for i in range(4):
        write(tmp_path / f"k{i}.png", GREY8)
    source = ImageSequence(tmp_path, loop=True)
    seen = []
    for frame in source:
        seen.append(frame.index)
        source.close()
    assert seen == [0] and not source.live and source.settings["loop"] is True
