"""``livedic bench paper``: the improved-WSO paper's figures and tables (command, runs, figures, report)."""

from livedic.bench.paper.command import PaperConfig, run_paper_benchmark

__all__ = ["PaperConfig", "run_paper_benchmark"]
