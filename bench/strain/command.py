"""``livedic bench strain``: strain fields and virtual extensometers against exact values (issue 11).

Three parts, each printed as a table, written as CSV and drawn in ``strain.png``
in the output folder (default ``results/strain``):

**a. Uniform strain** (the target: strain error RMS <= 1e-4 at a virtual strain
gauge VSG <= 100 px, 8-bit images, noise sigma = 1 grey level). Image pairs whose
deformed image is exact, from two generators that share nothing:

* ``speckle R=4``: livedic's Zhou-Goodson simulator (``dic.speckle.render`` of
  ``dic.speckle.affine``, the inverse map solved in closed form), its exact
  intensities scaled to 20..220 grey levels as ``bench.patterns.pair`` does;
* ``band-limited noise``: a random-phase sum of 2,048 sinusoids whose wave
  vectors are drawn from the Gaussian power spectrum of ``bench.patterns``'
  FFT-filtered noise (blur 1.6 px): a Gaussian random field evaluated
  *exactly* at any coordinate. The affine map turns each sinusoid into another
  sinusoid (wave vector A^-T k, a phase shift), so the deformed image is the
  same sum, evaluated separably (cos(a + b) = cos a cos b - sin a sin b, two
  matrix products). No image is interpolated anywhere.

Strain cases: uniaxial 0.1 %, 1 % and 5 % along y (-0.3 x that along x) and
a simple shear (dU/dY = 1 %, tensor shear 0.5 %), each with a sub-pixel
translation. ``dic.measure`` (IC-GN, as ``livedic run``; reliability-guided
improved-WSO start) measures a grid every 5 px; ``dic.strain.strain_field``
(engineering strain, which an affine field has exactly: ux, vy, (uy + vx)/2)
fits windows of 3..19 points. Printed: the RMS error of exx, eyy and exy in
microstrain at each VSG = (window - 1) x step + subset.

**b. The simulated tensile test** (``synthetic:tensile``, 1024 x 1024, ~1,000
points placed as ``livedic run`` places them: ``stream.session.p0.choose_p0`` and
``stream.session.points.build_points`` on the source's suggested ROI), tracked frame to
frame by ``stream.session.config.TrackingConfig().tracker``; strain and extensometers
by ``stream.stages.strain.StrainConfig(gauge_length=400).place(...)``, what
``livedic run --gauge-length 400`` computes. e_yy RMSE against the exact dV/dY
(central differences, h = 1e-3 px, of the frame's ``metadata["truth"]``),
inside the neck (|Y - y_neck| < neck width) and outside it; points within one
VSG of the plastic zone's ends (where the strain steps from the shoulders' to
the gauge's over 0.035 H) are left out of "outside". At the end of uniform
plastic strain and at the last frame. Extensometers: the largest
|error| / (50 microstrain + 0.5 % of the reading) over every frame (ISO 9513
class 0.5, relative part; the target is for L >= 400 px).

**c. A real test**, with ``--data DIR``: the muDIC dog-bone sequence
(``DIR/mudic_tensile_dogbone``, 18 frames every 5th of a polymer coupon that
necks), tracked the same way from its first frame. The axial extensometer's
strain per frame next to muDIC's mean true strain over its mesh and to the
strain muDIC's mesh nodes give between the same two material points (both a
reference, not truth), and whether the reading is monotone. muDIC's
coordinates are upside down with respect to the image rows (its y = H - 1 -
row; checked: its node displacements match ours within ~0.02 px once flipped,
and are 8 px off otherwise), so its mesh rows 209..1055 are image rows
994..1840 here.
"""

import os
import platform
import time

from livedic.bench.strain.dogbone import dogbone_study
from livedic.bench.strain.output import draw, write_csv
from livedic.bench.strain.tensile import tensile_study
from livedic.bench.strain.uniform import judge_uniform, uniform_strain_study


def _say(printed, log):
    def say(text=""):
        printed.append(text)
        log(text)
    return say


def run_strain_benchmark(*, quick=False, data=None, output="results/strain", log=print):
    """Run parts a, b (and c with ``data``), print them, write CSVs and ``strain.png`` into ``output``.

    Returns
    -------
    dict
        ``uniform`` rows, ``tensile`` results, ``dogbone`` results (or None), the verdict lines,
        ``files`` written and ``lines`` printed.
    """
    import numba

    printed = []
    say = _say(printed, log)
    started = time.perf_counter()
    os.makedirs(output, exist_ok=True)
    say(f"livedic bench strain{' --quick' if quick else ''}: {os.cpu_count()} CPU cores, {platform.machine()}, "
        f"numba {numba.__version__} ({numba.get_num_threads()} threads); results in {output}")
    say("")
    uniform = uniform_strain_study(quick=quick, say=say)
    uniform_met, default_met, lines, uniform_verdict = judge_uniform(uniform)
    if quick:
        uniform_verdict += "  [quick: 384x384, subset 21 only; the full run also tries subsets 31 and 41]"
    for line in lines:
        say(line)
    say(uniform_verdict)
    say("")
    tensile = tensile_study(quick=quick, say=say)
    say(tensile["verdict"])
    dogbone = None
    if data:
        say("")
        dogbone = dogbone_study(data, say=say)
        say(dogbone["verdict"])
    else:
        say("")
        say("(no --data: the real dog-bone sequence is skipped)")
    files = [write_csv(os.path.join(output, "uniform_strain.csv"), uniform),
             write_csv(os.path.join(output, "tensile_strain.csv"), tensile["field_rows"]),
             write_csv(os.path.join(output, "tensile_extensometers.csv"), tensile["extensometer_rows"])]
    if dogbone:
        files.append(write_csv(os.path.join(output, "dogbone_extensometer.csv"), dogbone["rows"]))
    files.append(draw(os.path.join(output, "strain.png"), uniform, tensile, dogbone))
    say("")
    say(f"written: {', '.join(os.path.basename(f) for f in files if f)} in {output}; "
        f"total {time.perf_counter() - started:.0f} s")
    return dict(uniform=uniform, uniform_met=uniform_met, uniform_default_met=default_met, tensile=tensile,
                dogbone=dogbone, verdicts=[uniform_verdict, tensile["verdict"]] + ([dogbone["verdict"]] if dogbone else []),
                files=[f for f in files if f], lines=printed)
