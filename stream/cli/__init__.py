"""The ``livedic`` command line (``main``: parser, dispatch, one-line errors); ``python -m livedic.stream.cli`` runs it.

This package re-exports the names its clients use (bench, tests), so ``from livedic.stream.cli import ...`` keeps
working; inside the package, modules import ``cli.main`` and the command modules directly.
"""

from livedic.stream.cli.main import (EXIT_BAD_INPUT, EXIT_SOURCE_LOST, LivedicParser, MeasureProgress, UsageError,
                                     build_parser, entry_point, main, measure_with_progress)

__all__ = ["EXIT_BAD_INPUT", "EXIT_SOURCE_LOST", "LivedicParser", "MeasureProgress", "UsageError", "build_parser",
           "entry_point", "main", "measure_with_progress"]
