"""Run pyALDIC-3D (PyPI ``al-dic-3d``) on one stereo pair sequence and write its 3D displacements as CSV.

Executed by ``livedic bench stereo --peer-python PATH`` with pyALDIC-3D's own Python, in a separate process:
pyALDIC-3D is never a livedic dependency, so this file imports nothing from livedic and reaches ``al_dic_3d``
through ``importlib`` only. pyALDIC-3D's headless pipeline (``al_dic_3d.runner.run_pipeline``, what its
``al-dic-3d run`` command does) is run with its defaults (``track_both`` strategy, accumulative reference,
AL-DIC global step, FFT initial guess, no quality gate) except the subset and grid step, given here so both
codes measure with the same subsets.

The calibration is livedic's stereo CAL.json body (``StereoCalibration.to_dict``: OpenCV's convention,
``X_right = R @ X_left + T``, mm), written as the OpenCV YAML (``cameraMatrix1``, ``distCoeffs1``, ..., ``R``,
``T``) pyALDIC-3D imports as ``format = "opencv_yaml"``: the same convention, no conversion of the numbers.

pyALDIC-3D measures on its own grid (every STEP px rounded down to a power of 2, at least 8 px, which it requires,
over the box of the points); its displacement at each
given point is interpolated linearly between its nodes (scipy), NaN outside them or where it has no result.

usage: python peer_aldic3d_runner.py CALIBRATION.json POINTS.csv OUT.csv SUBSET STEP LEFT0 RIGHT0 LEFT1 RIGHT1 ...
    POINTS.csv: x,y (left reference image px, one header line). Images: the reference pair then each deformed
    pair, left and right. OUT.csv: frame,x,y,U,V,W (mm, left camera frame; NaN: no result), one row a point
    and deformed frame (1, 2, ...).
"""

import importlib
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path


def write_opencv_yaml(calibration, path):
    """livedic's stereo calibration dict as the OpenCV stereo YAML pyALDIC-3D imports."""
    import cv2
    import numpy as np
    storage = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    try:
        for index, view in ((1, "left"), (2, "right")):
            storage.write(f"cameraMatrix{index}", np.asarray(calibration[view]["camera_matrix"], dtype=np.float64))
            storage.write(f"distCoeffs{index}",
                          np.asarray(calibration[view]["dist_coeffs"], dtype=np.float64).reshape(1, -1))
        storage.write("R", np.asarray(calibration["rotation"], dtype=np.float64))
        storage.write("T", np.asarray(calibration["translation_mm"], dtype=np.float64).reshape(3, 1))
    finally:
        storage.release()


def main(argv):
    calibration_path, points_path, out = argv[:3]
    subset, step = int(argv[3]), int(argv[4])
    images = argv[5:]
    if len(images) < 4 or len(images) % 2:
        raise SystemExit("give the reference pair and at least one deformed pair (left and right images)")
    import numpy as np
    from scipy.interpolate import LinearNDInterpolator
    runner = importlib.import_module("al_dic_3d.runner")
    with open(calibration_path, encoding="utf-8") as handle:
        calibration = json.load(handle)
    points = np.loadtxt(points_path, delimiter=",", skiprows=1, ndmin=2)
    work = tempfile.mkdtemp(prefix="livedic-aldic3d-")
    try:
        yaml = os.path.join(work, "calibration.yaml")
        write_opencv_yaml(calibration, yaml)
        # pyALDIC-3D's grid step must be a power of 2 and at least its smallest element (winsize_min, 8 px by default;
        # its validate_dicpara): the largest such not above STEP; the grid covers the points' box and one step more,
        # so every point has nodes around it
        step = max(runner.RunConfig.winsize_min, 1 << (max(step, 1).bit_length() - 1))
        x0, y0 = np.floor(points.min(axis=0)).astype(int) - step
        x1, y1 = np.ceil(points.max(axis=0)).astype(int) + step
        # its subset spans winsize + 1 px (winsize // 2 each side of the node, its icgn_solver): SUBSET - 1 if odd
        config = runner.RunConfig(calibration_file=Path(yaml), calibration_format="opencv_yaml",
                                  left=[os.path.abspath(p) for p in images[0::2]],
                                  right=[os.path.abspath(p) for p in images[1::2]],
                                  roi=(int(x0), int(x1), int(y0), int(y1)),
                                  output_dir=Path(work), winsize=subset - 1 if subset % 2 else subset,
                                  winstepsize=step)
        result = runner.run_pipeline(config)
        nodes = np.asarray(result.ref_coords, dtype=np.float64)
        displacement = np.asarray(result.reconstruction.displacement, dtype=np.float64)
        with open(out, "w", encoding="utf-8") as table:
            table.write("frame,x,y,U,V,W\n")
            for frame in range(1, displacement.shape[0]):
                good = np.all(np.isfinite(displacement[frame]), axis=1)
                print(f"pyALDIC-3D frame {frame}: {np.count_nonzero(good)} of {len(good)} nodes with a result",
                      file=sys.stderr)
                at_points = np.full((len(points), 3), np.nan)
                if np.count_nonzero(good) >= 3:
                    at_points = LinearNDInterpolator(nodes[good], displacement[frame][good])(points)
                for row in np.hstack([points, at_points]).tolist():
                    table.write(f"{frame}," + ",".join(map(repr, row)) + "\n")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
