"""The mechanics of a tensile test from its stress-strain curve: tensile properties (ISO 6892-1), Poisson ratio, fracture."""
