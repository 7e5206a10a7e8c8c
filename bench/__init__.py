"""Benchmarks of livedic.

* ``bench.paper``: ``livedic bench paper`` reproduces the figures and tables of
  the improved-WSO DIC paper (Li & Lei, *Laser Technology* 49(3), 2025) on
  simulated speckle images, adds Gaussian-noise variants the paper left out,
  and writes PNG figures, raw CSV/JSON numbers and ``report.md``.
* ``bench.speed``: ``livedic bench speed``, points per second per method.
"""
