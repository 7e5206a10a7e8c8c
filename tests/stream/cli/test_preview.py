"""Tests of stream/cli/preview.py: ``livedic preview`` draws the set-up of the source's first frame and says what
it placed; bad input is one line, exit 2, no picture. (The drawing itself: tests/stream/session/test_preview.py.)"""

import cv2
import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.stream.cli import main
from livedic.stream.cli.preview import first_frame


def test_preview_draws_the_set_up_and_says_what_it_placed(strip_images, tmp_path, capsys):
    out = tmp_path / "preview.png"
    code = main(["preview", "--source", f"images:{strip_images}", "--gauge-length", "200", "--n-points", "300",
                 "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    picture = cv2.imread(str(out))
    assert picture is not None and picture.shape[0] > 400 and picture.shape[1] > 600
    assert "over the speckled specimen" in err and "extensometer axial L0 200 px" in err
    assert "mean intensity gradient" in err and f"preview written to {out}" in err
    # the set-up panel draws the region's outline in its colour (yellow), the extensometers in theirs
    rgb = picture[:, :, ::-1].reshape(-1, 3).astype(int)
    for colour in ((255, 200, 0), (0, 200, 255), (255, 90, 200)):
        assert np.any(np.abs(rgb - colour).sum(axis=1) < 30), colour


@pytest.mark.parametrize("extra, message", [
    (["-o", "preview.jpg"], "is a PNG picture"),
    (["-o", "preview.png", "--roi", "polygon:1,2"], "expected polygon"),
    (["-o", "preview.png", "--exclude", "blob:1,2,3"], "unknown shape"),
    (["-o", "preview.png", "--mask", "missing.png"], "missing.png"),
    (["-o", "preview.png", "--gauge-length", "5000"], "extensometer axial"),
    (["-o", "preview.png", "--step", "5", "--max-points", "10"], "--max-points"),
])
def test_bad_input_is_one_line_exit_2_and_no_picture(strip_images, tmp_path, capsys, monkeypatch, extra, message):
    monkeypatch.chdir(tmp_path)
    code = main(["preview", "--source", f"images:{strip_images}", *extra])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "preview.png").exists() and not (tmp_path / "preview.jpg").exists()


def test_a_stereo_pair_is_drawn_left_view_above_right_view(tmp_path, capsys):
    out = tmp_path / "pair.png"
    pair = "stereo:synthetic:translate?size=160x128,synthetic:tensile?size=160x128"
    assert main(["preview", "--source", pair, "--n-points", "50", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "livedic: left view: 49 points" in err and "livedic: right view: 49 points" in err      # placed once
    assert f"preview written to {out}" in err and not [p for p in tmp_path.iterdir() if p.name != "pair.png"]
    picture = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    main(["preview", "--source", "synthetic:translate?size=160x128", "--n-points", "50", "-o", str(tmp_path / "one.png")])
    one = cv2.imread(str(tmp_path / "one.png"), cv2.IMREAD_GRAYSCALE)
    assert picture.shape[1] == one.shape[1] and picture.shape[0] > 1.8 * one.shape[0]    # two rows, one per view


def test_a_bad_stereo_source_is_one_line_exit_2_and_no_picture(tmp_path, capsys):
    code = main(["preview", "--source", "stereo:synthetic:translate", "-o", str(tmp_path / "p.png")])
    err = capsys.readouterr().err
    assert code == 2 and "a stereo pair takes two" in err and err.count("\n") == 1, err
    assert not list(tmp_path.iterdir())


def test_the_picture_goes_into_missing_folders(strip_images, tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "p.png"
    assert main(["preview", "--source", f"images:{strip_images}", "--n-points", "50", "-o", str(out)]) == 0
    assert cv2.imread(str(out)) is not None and f"preview written to {out}" in capsys.readouterr().err


def test_first_frame_is_the_sources_first_image_and_its_suggested_roi(strip_images):
    frame, suggested, _ = first_frame(f"images:{strip_images}")
    assert np.array_equal(frame.image, cv2.imread(str(strip_images / "f0.png"), cv2.IMREAD_GRAYSCALE))
    assert frame.index == 0
    frame, suggested, _ = first_frame("synthetic:tensile?size=96x128&pace=0")
    assert frame.image.shape == (128, 96) and suggested is not None      # the simulator's gauge section


def test_a_source_without_frames_is_a_source_error(tmp_path, monkeypatch):
    from livedic.acquire import sources

    class Empty:
        settings = None

        def __iter__(self):
            return iter(())

        def close(self):
            self.closed = True
    empty = Empty()
    monkeypatch.setattr(sources, "open_source", lambda uri, **options: empty)
    with pytest.raises(SourceError, match="images:nothing delivered no frame"):
        first_frame("images:nothing")
    assert empty.closed
