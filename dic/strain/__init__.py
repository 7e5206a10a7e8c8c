"""Strain from measured displacements: the strain field (field), virtual extensometers (extensometer), smooth fits (field_fit).

The package re-exports the strain field's names (formerly ``livedic.dic.strain``), so clients import them from here.
"""

from livedic.dic.strain.field import (DEFAULT_MEASURE, DEFAULT_WINDOW, MEASURES, MIN_POINTS, MIN_SPREAD,
                                      MIN_VALID_FRACTION, StrainField, StrainStatus, StrainWindow,
                                      displacement_gradients, principal_strains, strain_field, strain_tensor,
                                      strain_window, virtual_strain_gauge)

__all__ = ["MEASURES", "DEFAULT_MEASURE", "DEFAULT_WINDOW", "MIN_VALID_FRACTION", "MIN_POINTS", "MIN_SPREAD",
           "StrainStatus", "virtual_strain_gauge", "StrainWindow", "strain_window", "displacement_gradients",
           "strain_tensor", "principal_strains", "StrainField", "strain_field"]
