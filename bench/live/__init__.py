"""``livedic bench live``: the live pipeline on simulated 1 MP frames (receiver, cases, verdicts, main job, command)."""

from livedic.bench.live.cases import strain_out_numbers
from livedic.bench.live.receiver import StrainOutReceiver
from livedic.bench.live.command import run_live_benchmark
from livedic.bench.live.verdicts import HEADER

__all__ = ["HEADER", "StrainOutReceiver", "run_live_benchmark", "strain_out_numbers"]
