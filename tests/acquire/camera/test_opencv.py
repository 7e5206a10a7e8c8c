"""video: and v4l2: sources on FFV1 files written here (no V4L2 device on the test machines).

V4L2Camera runs the same OpenCVCapture path; on a file (FFmpeg backend) only
its device settings are no-ops, so the test checks the frame path and the
read-back plumbing, not a driver.
"""

import cv2
import numpy as np
import pytest

from livedic.acquire.base import SourceError
from livedic.acquire.camera.opencv import V4L2Camera, VideoFile, open_uri

pytestmark = pytest.mark.usefixtures("time_limit")

H, W, N = 48, 64, 6
RNG = np.random.default_rng(11)
FRAMES8 = [RNG.integers(0, 256, (H, W), dtype=np.uint8) for _ in range(N)]
FRAMES16 = [RNG.integers(0, 65536, (H, W), dtype=np.uint16) for _ in range(N)]


def write_video(path, frames, *, fourcc="FFV1", fps=25.0, colour=False):
    params = [cv2.VIDEOWRITER_PROP_IS_COLOR, 1 if colour else 0]
    if frames[0].dtype == np.uint16:
        params += [cv2.VIDEOWRITER_PROP_DEPTH, cv2.CV_16U]
    writer = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), fps,
                             (frames[0].shape[1], frames[0].shape[0]), params)
    assert writer.isOpened(), f"OpenCV cannot write {fourcc} {frames[0].dtype} here"
    for frame in frames:
        writer.write(frame)
    writer.release()
    return str(path)


@pytest.mark.parametrize("frames, pixel_format", [(FRAMES8, "Mono8"), (FRAMES16, "Mono16")], ids=["8bit", "16bit"])
def test_ffv1_grey_video_is_lossless(tmp_path, frames, pixel_format):
    path = write_video(tmp_path / "grey.mkv", frames)
    with open_uri(f"video:{path}") as source:
        got = list(source)
        settings = source.settings
    assert len(got) == N
    for i, frame in enumerate(got):
        assert frame.index == i and frame.pixel_format == pixel_format
        assert frame.image.dtype == frames[0].dtype and np.array_equal(frame.image, frames[i])
    assert [f.timestamp_ns for f in got] == [i * 40_000_000 for i in range(N)]   # 25 fps container times
    assert settings["width"] == W and settings["height"] == H and settings["frame_rate"] == 25.0
    assert settings["converted_to_grey"] is False and settings["notes"] == []
    assert settings["n_frames"] == N and settings["pixel_format"] == pixel_format


@pytest.mark.parametrize("fourcc, ext", [("FFV1", "mkv"), ("MJPG", "avi")])
def test_colour_video_is_converted_once_with_a_note(tmp_path, fourcc, ext, caplog):
    colour = [RNG.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(3)]
    path = write_video(tmp_path / f"colour.{ext}", colour, fourcc=fourcc, colour=True)
    with caplog.at_level("WARNING", logger="livedic.acquire.opencv"):
        with VideoFile(path) as source:
            got = list(source)
            settings = source.settings
    assert len(got) == 3 and all(f.image.ndim == 2 and f.image.dtype == np.uint8 for f in got)
    assert settings["converted_to_grey"] is True and "converted to grey" in settings["notes"][0]
    assert "note" in got[0].metadata and "note" not in got[1].metadata
    assert len([r for r in caplog.records if "converted to grey" in r.message]) == 1
    if fourcc == "FFV1":   # lossless: exactly OpenCV's BGR -> grey of what was written
        assert np.array_equal(got[0].image, cv2.cvtColor(colour[0], cv2.COLOR_BGR2GRAY))


def test_realtime_paces_the_file(tmp_path):
    import time
    path = write_video(tmp_path / "fast.mkv", FRAMES8, fps=100.0)
    start = time.monotonic()
    assert len(list(VideoFile(path, realtime=True))) == N
    assert time.monotonic() - start >= (N - 1) / 100 * 0.9


def test_video_errors(tmp_path):
    with pytest.raises(SourceError, match="nope.mkv: file not found"):
        open_uri(f"video:{tmp_path}/nope.mkv")
    (tmp_path / "junk.mkv").write_bytes(b"\x00junk" * 200)
    with pytest.raises(SourceError, match="junk.mkv: OpenCV could not open it"):
        open_uri(f"video:{tmp_path}/junk.mkv")
    with pytest.raises(SourceError, match="is a directory"):
        open_uri(f"video:{tmp_path}")
    with pytest.raises(SourceError, match="unknown video option"):
        open_uri(f"video:{tmp_path}/x.mkv", width=3)
    with pytest.raises(SourceError, match="not an OpenCV URI"):
        open_uri("file:x.mkv")


def test_truncated_video_ends_early_with_a_warning(tmp_path, caplog):
    path = write_video(tmp_path / "cut.mkv", [RNG.integers(0, 256, (240, 320), dtype=np.uint8) for _ in range(8)])
    data = open(path, "rb").read()
    with open(path, "wb") as file:
        file.write(data[: len(data) // 2])
    with caplog.at_level("WARNING", logger="livedic.acquire.opencv"):
        got = list(VideoFile(path))
    assert 0 < len(got) < 8
    assert any("truncated" in r.message for r in caplog.records)


def test_v4l2_code_path_on_a_file(tmp_path):
    """V4L2Camera through the FFmpeg backend: same frames, settings read back, end = lost device."""
    path = write_video(tmp_path / "dev.mkv", FRAMES16)
    camera = V4L2Camera(path, width=W, height=H, frame_rate=25, fourcc="Y16", exposure_us=5000, gain=2,
                        api=cv2.CAP_FFMPEG)
    got = []
    with pytest.raises(SourceError, match="stopped delivering frames"):
        with camera:
            for frame in camera:
                got.append(frame)
    assert [np.array_equal(f.image, FRAMES16[i]) for i, f in enumerate(got)] == [True] * N
    settings = camera.settings   # still described after close
    assert settings["source"] == "v4l2" and settings["width"] == W and settings["pixel_format"] == "Mono16"
    assert settings["requested"] == {"width": W, "height": H, "frame_rate": 25.0, "fourcc": "Y16 ",
                                     "exposure_us": 5000.0, "gain": 2.0}
    assert {"fourcc", "exposure_us", "gain", "frame_rate"} <= set(settings)   # read back from the driver


def test_v4l2_uri_and_errors():
    with pytest.raises(SourceError, match=r"/dev/video97: no such device \(video devices here: "):
        open_uri("v4l2:/dev/video97?width=640&height=480")
    with pytest.raises(SourceError, match="unknown v4l2 option"):
        open_uri("v4l2:/dev/video97?exposure=3")
    with pytest.raises(SourceError, match="fourcc='TOOLONG' must be 1 to 4 characters"):
        open_uri("v4l2:/dev/video97", fourcc="TOOLONG")
    with pytest.raises(SourceError, match="option width='-3': must be >= 1"):
        open_uri("v4l2:/dev/video97?width=-3")
    with pytest.raises(SourceError, match="option frame_rate='fast': not a number"):
        open_uri("v4l2:/dev/video97?frame_rate=fast")
