"""The ``livedic`` command line (``main``: parser, dispatch, one-line errors); ``python -m livedic.stream.cli`` runs it.

One module per command (``run``, ``measure``, ``preview``, ``replay``, ``export``, ``report``): its options and
what it prints; the work itself is done by the domain packages. This package re-exports the names its clients use
(bench, tests), so ``from livedic.stream.cli import ...`` keeps working.
"""

from livedic.stream.cli.main import EXIT_BAD_INPUT, EXIT_SOURCE_LOST, LivedicParser, build_parser, entry_point, main
from livedic.stream.cli.measure import MeasureProgress, measure_with_progress
from livedic.stream.session.parsing import UsageError

__all__ = ["EXIT_BAD_INPUT", "EXIT_SOURCE_LOST", "LivedicParser", "MeasureProgress", "UsageError", "build_parser",
           "entry_point", "main", "measure_with_progress"]
