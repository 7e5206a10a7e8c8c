"""Tests of bench/stereo.py: on a small rendered case the stereo session's U, V, W and extensometers in space match
the simulator's truth while one camera alone misreads the out-of-plane motion as strain; the command's options; the
open stereo peer's plumbing (pyALDIC-3D is never needed: stand-in scripts play its runner, and the calibration it is
given is checked by reading it back with OpenCV)."""

import json
import stat
import sys

import cv2
import numpy as np
import pytest

from livedic.acquire.simulator.lens import Lens
from livedic.acquire.simulator.stereo_rig import StereoRig
from livedic.bench.cli import main
from livedic.bench.peer_aldic3d_runner import write_opencv_yaml
from livedic.bench.peers import PeerStatus
from livedic.bench.stereo import ALDIC3D, PeerFailure, accuracy_case, grid_step, peer_lines, run_aldic3d, score_uvw


@pytest.fixture(scope="module")
def small_case():
    return accuracy_case(384, 4, 3000.0)


def test_stereo_removes_what_one_camera_reads_of_out_of_plane_motion(small_case):
    """0.5 mm away from the cameras and a 1 degree turn with 1 % strain: the extensometers in space within 150
    microstrain of the exact strain at every frame, one camera's off by more than 1,000."""
    errors3d, errors2d = small_case["extensometer_error_3d_microstrain"], small_case["extensometer_error_2d_microstrain"]
    assert max(errors3d.values()) < 150, errors3d
    assert min(errors2d.values()) > 1000, errors2d
    assert max(small_case["uvw_rmse_mm"]) < 0.005
    surface = small_case["surface_strain"]
    assert abs(surface["E_yy_mean"] - surface["E_yy_truth"]) < 5e-4
    assert small_case["ok_last"] >= 0.95 * small_case["points"]


def test_without_the_peer_livedic_is_scored_at_the_last_frame_and_the_peer_is_not_installed(small_case):
    peer = small_case["peer"]
    livedic, aldic = peer["codes"]
    assert peer["frame"] == 3 and livedic["status"] == "measured" and aldic["status"] == "not installed"
    assert livedic["ok"] >= 0.95 * small_case["points"] and max(livedic["uvw_rmse_mm"]) < 0.005
    lines = peer_lines(peer)
    assert "not installed" in lines[1] and "um over" in lines[0] and len(lines) == 2 and peer["common"] == []


def test_the_command_takes_its_options():
    from livedic.bench.cli import build_parser
    args = build_parser().parse_args(["bench", "stereo", "--quick", "-o", "out.json", "--peer-python", "/venv/python"])
    assert args.quick and args.output == "out.json" and args.handler.__name__ == "_cmd_bench_stereo"
    assert args.peer_python == "/venv/python"


def _rig_calibration() -> dict:
    lens = Lens((400, 300), -0.05, 0.01, 0.0005, -0.0003, focal_px=3000.0)
    return StereoRig.symmetric(lens, lens, distance_mm=300.0, angle_deg=25.0).calibration().to_dict()


def test_the_calibration_reaches_the_peer_as_opencv_stereo_yaml_unchanged(tmp_path):
    """livedic's rig (OpenCV's convention) read back from the YAML the runner writes: the same numbers."""
    calibration = _rig_calibration()
    path = str(tmp_path / "rig.yaml")
    write_opencv_yaml(calibration, path)
    storage = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    np.testing.assert_array_equal(storage.getNode("cameraMatrix1").mat(), calibration["left"]["camera_matrix"])
    np.testing.assert_array_equal(storage.getNode("cameraMatrix2").mat(), calibration["right"]["camera_matrix"])
    np.testing.assert_array_equal(storage.getNode("distCoeffs2").mat().ravel(), calibration["right"]["dist_coeffs"])
    np.testing.assert_array_equal(storage.getNode("R").mat(), calibration["rotation"])
    np.testing.assert_array_equal(storage.getNode("T").mat().ravel(), calibration["translation_mm"])
    storage.release()


def test_grid_step_is_the_spacing_of_a_grid_even_staggered():
    y, x = np.mgrid[10:200:8, 20:300:8].astype(float)
    assert grid_step(np.column_stack([x.ravel(), y.ravel()])) == 8
    staggered = np.column_stack([x.ravel() + (y.ravel() % 16 == 2) * 3, y.ravel()])
    assert grid_step(staggered) == 8


def _stand_in(tmp_path, body, runner_arguments=True):
    """An executable script standing in for pyALDIC-3D's python: argv = RUNNER CAL POINTS OUT SUBSET STEP IMAGES...
    (``runner_arguments``), else any."""
    path = tmp_path / "python_stand_in"
    unpack = "runner, cal, points, out, subset, step, *images = sys.argv[1:]\n" if runner_arguments else ""
    path.write_text(f"#!{sys.executable}\nimport json, sys\nimport numpy as np\n{unpack}{body}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return str(path)


POINTS = np.column_stack([np.arange(10.0, 90.0, 8.0), np.full(10, 40.0)])
TRUTH = np.column_stack([1e-3 * POINTS[:, 0], np.full(10, -0.02), np.linspace(0.1, 0.3, 10)])
IMAGES = [np.full((64, 96), 40 * k, dtype=np.uint8) for k in range(1, 5)]


def test_a_peer_table_is_read_at_the_points_and_scored_against_the_truth(tmp_path):
    """A stand-in answering U = x mm / 1000 (exact), V = 0 (0.02 mm off), W = 0.2 and no result at every other point:
    the RMSE is what those errors give over the half it answered, and it was handed the rig, the points and four
    images."""
    body = ("assert json.load(open(cal))['stereo'] and len(images) == 4 and (subset, step) == ('21', '8')\n"
            "xy = np.loadtxt(points, delimiter=',', skiprows=1).tolist()\n"
            "with open(out, 'w') as f:\n"
            "    f.write('frame,x,y,U,V,W\\n')\n"
            "    for i, (x, y) in enumerate(xy):\n"
            "        f.write(f'1,{x!r},{y!r},{x / 1000 if i % 2 == 0 else float(\"nan\")},0,0.2\\n')\n")
    displacement = run_aldic3d(_stand_in(tmp_path, body), IMAGES, _rig_calibration(), POINTS, 21, 8)
    ok = np.all(np.isfinite(displacement), axis=1)
    np.testing.assert_array_equal(ok, np.arange(10) % 2 == 0)
    result = score_uvw(ALDIC3D, displacement, ok, TRUTH)
    assert result.status is PeerStatus.MEASURED and (result.ok, result.points) == (5, 10)
    w_error = 0.2 - TRUTH[::2, 2]
    assert result.uvw_rmse_mm == pytest.approx([0.0, 0.02, float(np.sqrt(np.mean(w_error ** 2)))], abs=1e-12)


def test_a_failing_peer_or_a_short_table_is_reported_with_its_reason(tmp_path):
    failing = _stand_in(tmp_path, "sys.stderr.write('ValueError: winstepsize=10 must be a power of 2\\n'); sys.exit(1)")
    with pytest.raises(PeerFailure, match="exit code 1: ValueError: winstepsize=10"):
        run_aldic3d(failing, IMAGES, _rig_calibration(), POINTS, 21, 8)
    short = _stand_in(tmp_path, "open(out, 'w').write('frame,x,y,U,V,W\\n1,10.0,40.0,0,0,0\\n')")
    with pytest.raises(PeerFailure, match="unreadable result") as failure:
        run_aldic3d(short, IMAGES, _rig_calibration(), POINTS, 21, 8)
    assert "failed: unreadable result" in peer_lines({"frame": 1, "codes": [
        {"code": ALDIC3D, "status": "failed", "reason": str(failure.value)}]})[0]
    assert score_uvw("livedic", TRUTH, np.zeros(10, dtype=bool), TRUTH).status is PeerStatus.FAILED


def test_cli_peer_python_is_checked_in_one_line_exit_2(tmp_path, capsys):
    assert main(["bench", "stereo", "--quick", "--peer-python", str(tmp_path / "absent")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--peer-python" in err[0] and "not an executable file" in err[0]
    assert main(["bench", "stereo", "--quick", "--peer-python", _stand_in(tmp_path, "sys.exit(1)", False)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot import al_dic_3d" in err[0]
