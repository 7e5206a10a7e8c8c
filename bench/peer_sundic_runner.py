"""Run SUN-DIC (PyPI ``sun-dic``) on one image pair and write its displacements as CSV.

Executed by ``livedic bench peers`` with SUN-DIC's own Python (``--sundic-python``), in a separate
process: SUN-DIC is never a livedic dependency, so this file imports nothing from livedic and reaches
``sundic`` through ``importlib`` only. SUN-DIC's defaults are kept (IC-GN, affine shape function, bicubic
B-spline, its 5 x 5 Gaussian pre-blur, convergence 1e-4 px) except the subset, the grid, one CPU (no Ray
cluster) and the NZCC early exit, switched off (see ``main``).

usage: python peer_sundic_runner.py REFERENCE DEFORMED OUT.csv SUBSET STEP X0 Y0 X1 Y1
    The grid is every STEP px from (X0, Y0) up to (X1, Y1) inclusive, as SUN-DIC lays it from an ROI.
    OUT.csv: x,y,u,v,cznssd (cznssd 1e6 where SUN-DIC set no result).
"""

import importlib
import os
import shutil
import sys
import tempfile


def main(argv):
    reference, deformed, out = argv[:3]
    subset, step, x0, y0, x1, y1 = (int(value) for value in argv[3:9])
    sundic = importlib.import_module("sundic.sundic")
    settings_module = importlib.import_module("sundic.settings")
    work = tempfile.mkdtemp(prefix="livedic-sundic-")
    try:
        images = os.path.join(work, "images")
        os.mkdir(images)
        extension = os.path.splitext(reference)[1]
        shutil.copy(reference, os.path.join(images, "0" + extension))
        shutil.copy(deformed, os.path.join(images, "1" + extension))
        settings = settings_module.Settings()
        settings.ImageFolder = images
        settings.CPUCount = 1
        settings.DebugLevel = 0
        settings.SubsetSize = subset
        settings.StepSize = step
        settings.ROI = [x0, y0, x1 - x0 + 1, y1 - y0 + 1]
        # SUN-DIC stops iterating once NZCC exceeds NZCCThreshold (0.999 by default): on a clean pair that is
        # after the first step, far from converged; 1.0 leaves its displacement criterion (1e-4 px) in charge
        settings.NZCCThreshold = 1.0
        result = sundic.planarDICLocal(settings, os.path.join(work, "results.sdic"))[-1]
        ids = sundic.CompID
        with open(out, "w") as table:
            table.write("x,y,u,v,cznssd\n")
            for row in result.reshape(-1, result.shape[-1]):
                values = (float(row[index]) for index in (ids.XDispID, ids.YDispID, ids.CZNSSDID))
                table.write(f"{row[ids.XCoordID]:.0f},{row[ids.YCoordID]:.0f}," + ",".join(map(repr, values)) + "\n")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
