"""Tests of bench/stereo.py: on a small rendered case the stereo session's U, V, W and extensometers in space match
the simulator's truth while one camera alone misreads the out-of-plane motion as strain; the command's options."""

import pytest

from livedic.bench.stereo import accuracy_case


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


def test_the_command_takes_its_options():
    from livedic.bench.cli import build_parser
    args = build_parser().parse_args(["bench", "stereo", "--quick", "-o", "out.json"])
    assert args.quick and args.output == "out.json" and args.handler.__name__ == "_cmd_bench_stereo"
