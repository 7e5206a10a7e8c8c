"""``livedic bench strain``: strain fields and extensometers against exact values (uniform, tensile, dog-bone)."""

from livedic.bench.strain.command import run_strain_benchmark
from livedic.bench.strain.dogbone import DOGBONE, DOGBONE_MESH, dogbone_study
from livedic.bench.strain.tensile import tensile_study
from livedic.bench.strain.uniform import (GENERATORS, STRAIN_CASES, render_waves, uniform_pair, uniform_strain_study,
                                          wave_field)

__all__ = ["DOGBONE", "DOGBONE_MESH", "GENERATORS", "STRAIN_CASES", "dogbone_study", "render_waves",
           "run_strain_benchmark", "tensile_study", "uniform_pair", "uniform_strain_study", "wave_field"]
