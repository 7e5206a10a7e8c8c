"""livedic's measurement core: pure functions on numpy arrays.

Correlation (ZNCC), integer-pixel search (exhaustive, coarse-fine, PSO, WSO,
improved WSO), sub-pixel refinement (surface fit, gradient, Newton-Raphson,
improved surface fit, IC-GN) and an exact speckle simulator. No I/O, no threads.
"""

from livedic.dic.correlation import zncc
from livedic.dic.measure import SEARCH_METHODS, SUBPIXEL_METHODS, measure
from livedic.dic.result import Measurement
from livedic.dic.status import Status

__all__ = ["measure", "zncc", "Measurement", "Status", "SEARCH_METHODS", "SUBPIXEL_METHODS"]
