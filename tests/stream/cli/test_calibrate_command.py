"""``livedic calibrate``: CAL.json from simulated target images; bad inputs are one line, exit 2, nothing written."""

import json

import cv2
import pytest

from livedic.acquire.calibration import read_calibration
from livedic.dic.calibration import CalibrationError
from livedic.stream.cli.main import main


@pytest.fixture(scope="module")
def views(tmp_path_factory):
    from livedic.acquire.simulator.lens import Lens
    from livedic.acquire.simulator.targets import calibration_views, plane_view, render_target
    from livedic.dic.calibration import parse_target

    folder = tmp_path_factory.mktemp("views")
    lens = Lens((384, 384), k1=-0.12)
    spec = parse_target("chessboard:7x5")
    for i, pose in enumerate(calibration_views(spec, 10.0, lens)[:5]):
        cv2.imwrite(str(folder / f"view_{i}.png"), render_target(spec, 10.0, lens, pose, seed=i))
    cv2.imwrite(str(folder / "plane.png"), render_target(spec, 10.0, lens, plane_view(spec, 10.0, lens, 2.5), seed=9))
    return folder


def test_calibrate_writes_a_calibration_with_its_scale(views, tmp_path, capsys):
    out = tmp_path / "cal.json"
    code = main(["calibrate", str(views), "--target", "chessboard:7x5", "--square", "10", "-o", str(out),
                 "--plane", str(views / "plane.png")])
    printed = capsys.readouterr().out
    assert code == 0 and "px/mm" in printed and "reprojection RMS" in printed
    document = json.loads(out.read_text())
    assert (document["format"], document["version"]) == ("livedic-calibration", 1)
    calibration = read_calibration(out)
    assert calibration.image_size == (384, 384) and len(calibration.images) == 6
    assert abs(calibration.px_per_mm - 2.5) < 0.05


@pytest.mark.parametrize("arguments, says", [
    (["--target", "chessboard:6x5", "--square", "10"], "found in 0 of 6"),
    (["--target", "chessboard:7", "--square", "10"], "--target"),
    (["--target", "chessboard:7x5", "--square", "0"], "--square"),
])
def test_bad_inputs_are_one_line_and_write_nothing(views, tmp_path, capsys, arguments, says):
    out = tmp_path / "cal.json"
    code = main(["calibrate", str(views), *arguments, "-o", str(out)])
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and says in error and error.startswith("livedic: error:")
    assert not out.exists()


def test_a_calibration_file_that_does_not_parse_is_refused(tmp_path):
    bad = tmp_path / "cal.json"
    bad.write_text("{not json")
    with pytest.raises(CalibrationError, match="does not parse"):
        read_calibration(bad)
    bad.write_text(json.dumps({"format": "livedic-calibration", "version": 1, "image_size": [10, 10]}))
    with pytest.raises(CalibrationError, match="missing"):
        read_calibration(bad)


def test_run_refuses_a_calibration_of_another_resolution_before_any_output(tmp_path, capsys):
    import numpy as np

    from livedic.acquire.calibration import write_calibration
    from livedic.dic.calibration import CameraCalibration

    cal = tmp_path / "cal.json"
    K = np.array([[512.0, 0, 255.5], [0, 512.0, 255.5], [0, 0, 1]])
    write_calibration(cal, CameraCalibration((512, 512), K, np.array([-0.12, 0, 0, 0, 0]), 0.1, (), "chessboard:9x6",
                                             5.0))
    record = tmp_path / "session.mcap"
    code = main(["run", "--source", "synthetic:tensile?size=256x256&frames=3&pace=0", "--calibration", str(cal),
                 "--viewer", "none", "--record", str(record)])
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2 and "made for 512x512" in error and "256x256" in error
    assert not record.exists()
